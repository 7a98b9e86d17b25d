"""`--views` on every verb that reads data (docs/data.md), and what it chooses reaching compare-encoders' outputs."""

from __future__ import annotations

import json
from pathlib import Path

import click
import typer.main
from rrd import entity_paths
from synthetic import VIEWS, write_project_dataset
from typer.testing import CliRunner

from rfr_viz.cli.app import app
from rfr_viz.paths import CAMERA_ROOT, camera

DATA_PARAMETERS = {"data", "trajectory", "episode"}  # the argument (or `--data` option) naming the data read


def test_every_verb_that_reads_data_takes_views() -> None:
    group = typer.main.get_command(app)
    context = click.Context(group)
    reading = []
    for name in group.list_commands(context):
        verb = group.get_command(context, name)
        assert verb is not None
        if {parameter.name for parameter in verb.params} & DATA_PARAMETERS:
            reading.append(name)
            assert "--views" in {flag for parameter in verb.params for flag in parameter.opts}, name
    assert {"build-memory", "detect", "evaluate", "compare-encoders", "review", "watch"} <= set(reading)


def test_compare_encoders_views_front_keeps_only_the_front_camera(
    tmp_path: Path, tiny_checkpoint: tuple[Path, Path]
) -> None:
    config_json, checkpoint = tiny_checkpoint
    clip = f"open_clip:{config_json}:{checkpoint}"
    data = write_project_dataset(tmp_path / "data", tasks=("pick_cube",), episodes=2, length=4)
    assert len(VIEWS) > 1 and "front" in VIEWS
    out = tmp_path / "out"
    result = CliRunner().invoke(
        app,
        [
            *("compare-encoders", str(data), "--encoder", "pixels", "--encoder", clip, "--out", str(out)),
            *("--target-fpr", "0.5", "--recordings", "1", "--cache-dir", str(tmp_path / "cache")),
            *("--views", "front"),
        ],
    )
    assert result.exit_code == 0, result.output
    for memory in ("memory-pixels", "memory-tinyvit-test"):
        entries = (out / memory / "entries.jsonl").read_text().splitlines()
        assert entries and {json.loads(entry)["view"] for entry in entries} == {"front"}
    (recording,) = (out / "recordings").glob("*.rrd")
    cameras = {path for path in entity_paths(recording) if path.startswith(f"{CAMERA_ROOT}/")}
    assert cameras == {camera("front")}
