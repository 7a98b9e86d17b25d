"""The library is usable without Rerun and without the heavy optional parts: importing it loads none."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from synthetic import write_project_dataset

HEAVY = ("rerun", "umap", "pybullet", "torch", "open_clip", "av", "httpx")


def test_import_robofailring_loads_no_heavy_package() -> None:
    probe = (
        "import json, sys; import robofailring; "
        f"print(json.dumps(sorted({{m.split('.')[0] for m in sys.modules}} & set({list(HEAVY)!r}))))"
    )
    loaded = json.loads(
        subprocess.run([sys.executable, "-c", probe], check=True, capture_output=True, text=True).stdout
    )
    assert loaded == []


#: train-encoder in a fresh interpreter where pybullet (the sim extra) cannot be imported.
WITHOUT_SIM = """
import json, sys
sys.modules["pybullet"] = None
import robofailring.jobs.train_encoder
imported = [name for name, module in sys.modules.items() if module is not None]
loaded = sorted(m for m in imported if m.split(".")[0] == "pybullet" or m.startswith("robofailring.sim"))
from typer.testing import CliRunner
from robofailring.cli.verbs import app
randomize = CliRunner().invoke(app, ["train-encoder", *sys.argv[1:], "--randomize", "4"])
print(json.dumps({"loaded": loaded, "randomize": [randomize.exit_code, randomize.output]}))
"""


def test_train_encoder_needs_the_simulator_only_to_randomize(tmp_path: Path) -> None:
    """The `clip` extra alone trains an encoder (docs/install.md): only --randomize imports the simulator."""
    data = write_project_dataset(tmp_path / "data", tasks=("pick_cube",), episodes=1, length=3)
    result = subprocess.run(
        [sys.executable, "-c", WITHOUT_SIM, str(data), "--out", str(tmp_path / "encoder")],
        capture_output=True,
        text=True,
        check=True,
    )
    outcome = json.loads(result.stdout)
    assert outcome["loaded"] == []
    code, output = outcome["randomize"]
    assert code == 1 and output.strip().splitlines() == [
        "error: pybullet is not installed; it comes with the sim extra (the simulated default dataset): "
        'install robofailring[sim] (pip install "robofailring[sim]")'
    ]
    assert not (tmp_path / "encoder").exists()
