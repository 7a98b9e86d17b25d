"""CLI verbs that combine the library with recordings: evaluate (and, from here, the demo)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from robofailring.cli import CacheOption, DeviceOption, EncoderOption, app, exit_with_error
from robofailring.errors import RoboFailRingError


@app.command("evaluate")
def evaluate_cmd(
    data: Annotated[Path, typer.Argument(help="Dataset: the training split's failures form the memory.")],
    out: Annotated[Path, typer.Option("--out", help="Folder for <name>.md, <name>.json and <name>.rrd.")],
    encoder: EncoderOption = "pixels",
    memory: Annotated[Path | None, typer.Option(help="Use this memory instead of building one.")] = None,
    test_data: Annotated[
        Path | None, typer.Option(help="Test on this dataset (e.g. out-of-distribution).")
    ] = None,
    train_split: Annotated[str, typer.Option(help="Split whose failures build the memory.")] = "train",
    test_split: Annotated[str, typer.Option(help="Split to test on.")] = "test",
    k: Annotated[int, typer.Option(help="Neighbours retrieved per query.")] = 5,
    name: Annotated[str, typer.Option(help="Name of this evaluation in the outputs.")] = "evaluation",
    cache_dir: CacheOption = None,
    device: DeviceOption = None,
) -> None:
    """The paper's evaluation: Recall/FPR at δ = 0.85…0.95 and a fine sweep, T_s, per-type and per-view recall."""
    from rfr_viz.evaluation_recording import record_evaluation
    from robofailring.evaluation import EvaluateConfig, run_evaluation, write_evaluation

    config = EvaluateConfig(
        data=data,
        out=out,
        encoder=encoder,
        memory=memory,
        test_data=test_data,
        train_split=train_split,
        test_split=test_split,
        k=k,
        name=name,
        cache_dir=cache_dir,
        device=device,
    )
    try:
        result = run_evaluation(config)
    except RoboFailRingError as error:
        exit_with_error(error)
    json_path, md_path = write_evaluation(result, out)
    rrd_path = record_evaluation([result], out=Path(out) / f"{name}.rrd")
    typer.echo(result.to_markdown())
    typer.echo(f"\nwrote {md_path}, {json_path} and {rrd_path} (open with: rerun {rrd_path})")
