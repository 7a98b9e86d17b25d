"""build-memory → calibrate → detect → replay → evaluate through the real CLI, on any dataset."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from typer.testing import CliRunner

from rfr_viz.cli.app import app


def invoke(arguments: Sequence[str], *, code: int = 0) -> Any:
    result = CliRunner().invoke(app, [str(a) for a in arguments])
    assert result.exit_code == code, result.output
    return result


def run_pipeline(
    tmp: Path, data: Path, *, trajectory: str, options: Sequence[str] = (), evaluate: Sequence[str] = ()
) -> dict[str, Any]:
    """Every verb on `data` with the same data options; the memory's info, detect's JSON and evaluate's JSON."""
    cache = ["--cache-dir", tmp / "cache"]
    memory, recordings, report = tmp / "memory", tmp / "recordings", tmp / "evaluation"
    invoke(["build-memory", data, "--out", memory, *options, *cache])
    invoke(
        ["calibrate", data, "--memory", memory, "--target-fpr", "0.5", "--split", "train", *options, *cache]
    )
    detected = invoke(
        ["detect", data, "--memory", memory, "--trajectory", trajectory, "--json", *options, *cache]
    )
    invoke(
        [
            "replay",
            data,
            "--memory",
            memory,
            "--trajectory",
            trajectory,
            "--out",
            recordings,
            *options,
            *cache,
        ]
    )
    invoke(["evaluate", data, "--out", report, "--target-fpr", "0.5", *options, *evaluate, *cache])
    info = invoke(["memory-info", memory, "--json"])
    return {
        "info": json.loads(info.stdout),
        "detect": json.loads(detected.stdout),
        "evaluation": json.loads((report / "evaluation.json").read_text()),
        "recordings": sorted(recordings.glob("*.rrd")),
        "memory": memory,
    }
