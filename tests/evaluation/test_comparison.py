"""Encoder comparison end to end: two encoders, one split, each memory calibrated, one table.

The `compare-encoders` verb runs once (module fixture); the library's results it computed and the files
it wrote are both checked on that one run.
"""

from __future__ import annotations

import json
import re
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import pytest
from synthetic import write_project_dataset
from typer.testing import CliRunner, Result

import rfr_viz.jobs.compare_encoders as encoder_comparison
import robofailring.encoders as encoders
from rfr_viz.cli.app import app
from rfr_viz.jobs.compare_encoders import EncoderComparison
from rfr_viz.viewer.rrd import verify_recording
from robofailring.data.selection import DataSelection
from robofailring.jobs.compare_encoders import CompareEncodersConfig, compare_encoders, comparison_table

pytestmark = pytest.mark.slow  # simulation or end-to-end: the full lane only (scripts/test.sh)


@dataclass(frozen=True)
class Compared:
    """One `compare-encoders` run: the command's result, its output folder and what its job returned."""

    cli: Result
    out: Path
    comparison: EncoderComparison
    loads: Counter[str]  # real encoder loads during the run, by spec


@pytest.fixture(scope="module")
def compared(tmp_path_factory: pytest.TempPathFactory, tiny_checkpoint: tuple[Path, Path]) -> Compared:
    """The verb as a user runs it; the job it calls is wrapped only to keep what that job returned."""
    config_json, checkpoint = tiny_checkpoint
    root = tmp_path_factory.mktemp("compare")
    data = write_project_dataset(root / "data", tasks=("pick_cube",), episodes=4)
    returned: list[EncoderComparison] = []
    job = encoder_comparison.run_encoder_comparison
    loads: Counter[str] = Counter()
    real_load = encoders._load  # what every open and load of an encoder builds it with

    def counting_load(
        spec: encoders.EncoderSpec, device: str | None, cache_dir: Path | None
    ) -> encoders.Encoder:
        loads[str(spec)] += 1
        return real_load(spec, device, cache_dir)

    def keep(config: CompareEncodersConfig, *, recordings: int = 3) -> EncoderComparison:
        returned.append(job(config, recordings=recordings))
        return returned[-1]

    encoders._loaded_encoder.cache_clear()
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(encoder_comparison, "run_encoder_comparison", keep)
        patch.setattr(encoders, "_load", counting_load)
        result = CliRunner().invoke(
            app,
            [
                "compare-encoders",
                str(data),
                "--encoder",
                "pixels",
                "--encoder",
                f"open_clip:{config_json}:{checkpoint}",
                "--out",
                str(root / "out"),
                "--target-fpr",
                "0.5",
                "--recordings",
                "2",
                "--cache-dir",
                str(root / "cache"),
            ],
        )
    assert result.exit_code == 0, result.output
    (comparison,) = returned
    return Compared(cli=result, out=root / "out", comparison=comparison, loads=loads)


def test_two_encoders_side_by_side(compared: Compared) -> None:
    results = compared.comparison.results
    assert [r.name for r in results] == ["pixels", "tinyvit-test"]
    for result in results:
        manifest = json.loads((Path(result.memory) / "manifest.json").read_text())
        assert manifest["calibration"]["encoder"] == result.encoder == manifest["encoder"]
        assert (
            result.operating_delta == manifest["calibration"]["rules"]["paper"]["threshold"]
            and result.calibrated
        )
        assert result.failures == 6 and result.successes == 2
    table = comparison_table(results)
    assert (
        table.count("\n") == 1 + 2 * 3
        and "| contrast |" in table
        and table.count("| dense, change |") == 2 * 3  # each encoder's memory, as every table says
        and "`pixels-v2-24px-512d`" in table
        and "open_clip:TinyViT-test" in table
    )
    # one way to open an encoder: building, calibrating, evaluating and recording load each one once
    assert compared.loads["pixels"] == 1 and sorted(compared.loads.values()) == [1, 1], compared.loads


def test_needs_two_encoders(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="at least two"):
        compare_encoders(
            CompareEncodersConfig(data=DataSelection(tmp_path), out=tmp_path, encoders=("pixels",))
        )


def test_compare_encoders_verb_writes_table_and_recordings(compared: Compared) -> None:
    assert compared.cli.exit_code == 0, compared.cli.output
    assert (compared.out / "comparison.md").read_text().count("\n") == 2 + 2 * 3
    recordings = sorted((compared.out / "recordings").glob("*.rrd"))
    assert len(recordings) == 2
    for path in recordings:
        verify_recording(path)


def test_two_checkpoints_of_one_model_keep_two_memories_and_one_encoder_twice_is_refused(
    tmp_path: Path, tiny_checkpoint: tuple[Path, Path]
) -> None:
    """Issue 53's worked example found it: two encoders of one slug (one model, two checkpoints) were built into
    one `memory-<slug>` folder, the second over the first, and every recording showed the second. Each now
    has its own folder (`…-2`), its own evaluation and its own identity; one encoder given twice is refused."""
    import torch

    config_json, checkpoint = tiny_checkpoint
    other = tmp_path / "other.pt"
    state = torch.load(checkpoint, map_location="cpu")
    torch.save(
        {"state_dict": {k: v + 0.01 if v.is_floating_point() else v for k, v in state["state_dict"].items()}},
        other,
    )
    data = write_project_dataset(tmp_path / "data", tasks=("pick_cube",), episodes=4)
    first, second = f"open_clip:{config_json}:{checkpoint}", f"open_clip:{config_json}:{other}"
    out = tmp_path / "out"
    common = [
        "--out",
        str(out),
        "--target-fpr",
        "0.5",
        "--recordings",
        "1",
        "--cache-dir",
        str(tmp_path / "c"),
    ]
    result = CliRunner().invoke(
        app, ["compare-encoders", str(data), "--encoder", first, "--encoder", second, *common]
    )
    assert result.exit_code == 0, result.output
    identities = [
        json.loads((out / name / "manifest.json").read_text())["encoder"]
        for name in ("memory-tinyvit-test", "memory-tinyvit-test-2")
    ]
    assert len(set(identities)) == 2 and all(i.startswith("open_clip:TinyViT-test:file-") for i in identities)
    rows = re.findall(r"^\| `(open_clip:[^`]+)`", (out / "comparison.md").read_text(), flags=re.M)
    assert set(rows) == set(identities)  # each row's memory is its own encoder's

    again = CliRunner().invoke(
        app, ["compare-encoders", str(data), "--encoder", "pixels", "--encoder", "pixels@torch", *common]
    )
    assert again.exit_code != 0 and "--encoder pixels is given twice" in again.output
