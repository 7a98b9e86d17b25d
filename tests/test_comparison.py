"""Encoder comparison end to end: two encoders, one split, each memory calibrated, one table."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import pytest
from synthetic import write_project_dataset

from robofailring.comparison import CompareEncodersConfig, compare_encoders, comparison_table

pytestmark = pytest.mark.slow  # simulation or end-to-end: the full lane only (scripts/test.sh)


def test_two_encoders_side_by_side(
    tmp_path: Path, tiny_checkpoint: tuple[Path, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    import robofailring.encoders as encoders

    loads: Counter[str] = Counter()
    real_load = encoders.load_encoder

    def counting_load(spec: str | encoders.EncoderSpec, *, device: str | None = None) -> encoders.Encoder:
        loads[str(spec)] += 1
        return real_load(spec, device=device)

    encoders._loaded_encoder.cache_clear()
    monkeypatch.setattr(encoders, "load_encoder", counting_load)
    config_json, checkpoint = tiny_checkpoint
    data = write_project_dataset(tmp_path / "data", tasks=("pick_cube",), episodes=4)
    clip = f"open_clip:{config_json}:{checkpoint}"
    results = compare_encoders(
        CompareEncodersConfig(
            data=data,
            out=tmp_path / "out",
            encoders=("pixels", clip),
            target_fpr=0.5,
            cache_dir=tmp_path / "cache",
        )
    )
    assert [r.name for r in results] == ["pixels", "tinyvit-test"]
    assert loads == Counter({"pixels": 1, clip: 1})  # each encoder opened once (build, calibrate, evaluate)
    for result in results:
        manifest = json.loads((Path(result.memory) / "manifest.json").read_text())
        assert manifest["calibration"]["encoder"] == result.encoder == manifest["encoder"]
        assert result.operating_delta == manifest["calibration"]["delta"] and result.calibrated
        assert result.failures == 6 and result.successes == 2
    table = comparison_table(results)
    assert (
        table.count("\n") == 1 + 2 * 2
        and "| contrast |" in table
        and "`pixels-v2-24px-512d`" in table
        and "open_clip:TinyViT-test" in table
    )


def test_needs_two_encoders(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="at least two"):
        compare_encoders(CompareEncodersConfig(data=tmp_path, out=tmp_path, encoders=("pixels",)))


def test_compare_encoders_verb_writes_table_and_recordings(
    tmp_path: Path, tiny_checkpoint: tuple[Path, Path]
) -> None:
    from typer.testing import CliRunner

    from rfr_viz.cli import app
    from rfr_viz.viewer import verify_recording

    config_json, checkpoint = tiny_checkpoint
    data = write_project_dataset(tmp_path / "data", tasks=("pick_cube",), episodes=4)
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
            str(tmp_path / "out"),
            "--target-fpr",
            "0.5",
            "--recordings",
            "2",
            "--cache-dir",
            str(tmp_path / "cache"),
        ],
    )
    assert result.exit_code == 0, result.output
    assert (tmp_path / "out" / "comparison.md").read_text().count("\n") == 2 + 2 * 2
    recordings = sorted((tmp_path / "out" / "recordings").glob("*.rrd"))
    assert len(recordings) == 2
    for path in recordings:
        verify_recording(path)
