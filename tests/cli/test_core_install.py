"""`pip install robofailring` without extras: a fresh venv runs the core verbs and the step API, and
every verb that needs an extra ends in one line naming it (docs/install.md, "Install").

The venv gets pip from this interpreter (`pip --python`), the project as a wheel built from the
checkout, and its core dependencies from the package index (pip's own cache, ~/.cache/pip, is reused
between runs; PIP_FIND_LINKS is honoured).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from synthetic import write_aha_dataset, write_episode

from robofailring.extras import EXTRAS

pytestmark = pytest.mark.slow

CHECKOUT = Path(__file__).resolve().parents[2]
#: Distributions that only an extra installs: none of them may come with the core install.
HEAVY = ("torch", "torchvision", "open-clip-torch", "rerun-sdk", "umap-learn", "numba", "pybullet", "av")
EPISODE = "pick_cube_grasp_wp2_episode0"


@pytest.fixture(scope="module")
def core(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A venv holding the core install, and an AHA-layout folder of failures and one of successes."""
    root = tmp_path_factory.mktemp("core-install")
    venv = root / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    pip = [sys.executable, "-m", "pip", "--python", str(venv / "bin" / "python"), "install", "--quiet"]
    install = subprocess.run(
        [*pip, "--no-compile", str(CHECKOUT)],
        env=_clean_env(root),
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert install.returncode == 0, install.stdout + install.stderr
    failures = write_aha_dataset(root / "failures")
    for task in ("pick_cube", "push_cube"):
        for episode in range(3):
            folder = root / "successes" / f"{task}_success_episode{episode}"
            write_episode(folder, task, None, layout="aha", shift=episode)
    return {"root": root, "bin": venv / "bin", "failures": failures, "successes": root / "successes"}


@pytest.fixture(scope="module")
def memory(core: dict[str, Path]) -> Path:
    """The failures' memory, built by the core install's build-memory with the weight-free encoder."""
    out = core["root"] / "memory"
    built = _cli(core, "build-memory", core["failures"], "--encoder", "pixels", "--out", out)
    assert built.returncode == 0, built.stderr
    return out


def _clean_env(root: Path) -> dict[str, str]:
    """This environment without anything that would import the checkout or this venv's packages."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}
    env.update(ROBOFAILRING_PROGRESS="0", ROBOFAILRING_CACHE=str(root / "cache"))
    return env


def _run(core: dict[str, Path], *args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(a) for a in args],
        cwd=core["root"],  # not the checkout: nothing of it is importable from here
        env=_clean_env(core["root"]),
        capture_output=True,
        text=True,
        timeout=300,
    )


def _cli(core: dict[str, Path], *args: str | Path) -> subprocess.CompletedProcess[str]:
    return _run(core, core["bin"] / "robofailring", *args)


INSTALLED = """
import importlib.metadata, json, sys
import robofailring
def installed(name):
    try:
        importlib.metadata.version(name)
    except importlib.metadata.PackageNotFoundError:
        return False
    return True
print(json.dumps({"heavy": [d for d in sys.argv[1:] if installed(d)], "package": robofailring.__file__}))
"""
STEP_API = """
import json, sys
from pathlib import Path
import robofailring
detector = robofailring.open_detector(sys.argv[1])
trajectory = robofailring.load_trajectory(Path(sys.argv[2]))
session = detector.session(trajectory.task)
alarms = [session.step({v: f[t] for v, f in trajectory.views.items()}).alarm for t in range(trajectory.length)]
print(json.dumps(alarms.index(True) if True in alarms else None))
"""


def test_core_install_pulls_no_extra(core: dict[str, Path]) -> None:
    result = _run(core, core["bin"] / "python", "-c", INSTALLED, *HEAVY)
    assert result.returncode == 0, result.stderr
    found = json.loads(result.stdout)
    assert found["heavy"] == []
    assert found["package"].startswith(str(core["bin"].parent))  # the installed package, not the checkout


def test_core_verbs_and_step_api_without_extras(core: dict[str, Path], memory: Path) -> None:
    helped = _cli(core, "--help")
    assert helped.returncode == 0 and "build-memory" in helped.stdout and "replay" in helped.stdout

    manifest = json.loads((memory / "manifest.json").read_text())
    # dense by default: at most tasks × failure types × episodes × views × frames 1-5 (no onset known), less
    # the frames that have not moved from the run's first (they would match every run's start)
    assert (manifest["failure_frames"], manifest["pairing"]) == ("dense", "change")
    assert 2 * 3 * 2 * 3 * 4 < manifest["count"] < 2 * 3 * 2 * 3 * 5

    calibrated = _cli(core, "calibrate", core["successes"], "--memory", memory, "--target-fpr", "0.2")
    assert calibrated.returncode == 0, calibrated.stderr
    delta = json.loads((memory / "manifest.json").read_text())["calibration"]["rules"]["paper"]["threshold"]
    assert -1.0 <= delta <= 1.0 + 1e-6  # just above the highest peak, which may be a cosine of 1

    detected = _cli(core, "detect", core["failures"] / EPISODE, "--memory", memory, "--json")
    assert detected.returncode == 0, detected.stderr
    report = json.loads(detected.stdout)
    assert (report["task"], report["episode"], report["delta"]) == (
        "pick_cube",
        EPISODE,
        pytest.approx(delta),
    )
    assert report["t_det"] is not None  # its own episode is in the memory: S⁻ reaches 1

    info = _cli(core, "memory-info", memory)
    assert info.returncode == 0 and f"{manifest['count']} × 1024-d" in info.stdout, info.stdout + info.stderr

    stepped = _run(core, core["bin"] / "python", "-c", STEP_API, memory, core["failures"] / EPISODE)
    assert stepped.returncode == 0, stepped.stderr
    assert json.loads(stepped.stdout) == report["t_det"]  # the step API and detect agree


@pytest.mark.parametrize(
    ("command", "extra"),
    [
        ("replay {failures} --memory {memory} --out {root}/recordings", "viz"),
        ("evaluate {failures} --out {root}/evaluation", "viz"),
        ("generate --out {root}/generated", "sim"),
        ("build-memory {failures} --encoder open_clip:ViT-B-32:openai --out {root}/clip-memory", "clip"),
        ("detect {failures}/" + EPISODE + " --memory {memory} --vlm-url http://vlm --vlm-model m", "vlm"),
    ],
)
def test_a_verb_whose_extra_is_missing_names_it_in_one_line(
    core: dict[str, Path], memory: Path, command: str, extra: str
) -> None:
    where = {"failures": core["failures"], "memory": memory, "root": core["root"]}
    result = _cli(core, *command.format(**where).split())
    assert result.returncode == 1, result.stdout + result.stderr  # an error of the environment
    errors = [line for line in result.stderr.splitlines() if not line.startswith("warning:")]
    assert len(errors) == 1 and errors[0].startswith("error: "), result.stderr  # no traceback
    assert f"install robofailring[{extra}]" in errors[0]
    assert any(distribution in errors[0] for distribution in EXTRAS[extra].values())
