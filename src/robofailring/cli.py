"""The `robofailring` command line: thin typer verbs over the library."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from robofailring.data.layouts import read_project_manifest
from robofailring.errors import RoboFailRingError
from robofailring.progress import progress_bar

app = typer.Typer(
    name="robofailring",
    help="Retrieval-based robot failure detection (RoboFailRing) and its Rerun recordings.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)

EncoderOption = Annotated[
    str,
    typer.Option(
        "--encoder",
        help="`pixels` (weight-free) or `open_clip:<model>[:<pretrained tag or checkpoint path>]`.",
    ),
]
CacheOption = Annotated[
    Path | None, typer.Option("--cache-dir", help="Embedding cache folder (default ~/.cache/robofailring).")
]
DeviceOption = Annotated[
    str | None, typer.Option("--device", help="torch device (default: cuda if available).")
]
ScoreOption = Annotated[
    str | None,
    typer.Option(
        "--score",
        help="Scoring rule: `paper` (S_t ≥ δ) or `contrast` (C_t = S⁻_t − S⁺_t ≥ γ); "
        "default: contrast when the memory has success runs, else paper.",
    ),
]
GammaOption = Annotated[
    float | None,
    typer.Option(help="Contrast threshold γ (default: the memory's calibrated γ, else 0)."),
]


def exit_with_error(error: Exception) -> None:
    typer.secho(f"error: {error}", fg=typer.colors.RED, err=True)
    raise typer.Exit(code=2)


@app.command("generate")
def generate_cmd(
    out: Annotated[Path, typer.Option("--out", help="Dataset folder to write (the project's layout).")],
    tasks: Annotated[
        list[str] | None, typer.Option("--tasks", help="Tasks to run (repeatable); default all.")
    ] = None,
    episodes: Annotated[
        int, typer.Option(help="Episodes per task and kind (failure family or success).")
    ] = 2,
    success_episodes: Annotated[
        int | None, typer.Option(help="Success episodes per task (default: --episodes).")
    ] = None,
    seed: Annotated[int, typer.Option(help="Base seed: the same seed gives identical images.")] = 0,
    ood: Annotated[
        bool, typer.Option("--ood", help="Out-of-distribution lighting, colours, cameras, sizes.")
    ] = False,
    image_size: Annotated[int, typer.Option("--image-size", help="Square image size in pixels.")] = 128,
    frames: Annotated[int, typer.Option(help="Frames per episode.")] = 40,
    workers: Annotated[int, typer.Option(help="Simulation processes.")] = 2,
) -> None:
    """Simulate the embedded FailGen (PyBullet Panda): failures injected by perturbing keyframes, plus successes."""
    from robofailring.sim import TASKS, GenerateConfig, generate_dataset

    try:
        config = GenerateConfig(
            out=out,
            tasks=tuple(tasks) if tasks else TASKS,
            episodes=episodes,
            success_episodes=success_episodes,
            seed=seed,
            ood=ood,
            image_size=image_size,
            frames=frames,
            workers=workers,
        )
        with progress_bar(total=config.total_episodes, desc="simulating", unit="episode") as bar:
            root = generate_dataset(config, progress=bar.update)
    except (RoboFailRingError, ValueError) as error:
        exit_with_error(error)
    manifest = read_project_manifest(root)
    failures = sum(e["outcome"] == "failure" for e in manifest["episodes"])
    typer.echo(
        f"dataset {root}: {len(manifest['episodes'])} episodes ({failures} failures), {manifest['fps']} fps"
    )


@app.command("build-memory")
def build_memory_cmd(
    data: Annotated[Path, typer.Argument(help="Dataset root (AHA, ManiSkill-failgen or project layout).")],
    out: Annotated[Path, typer.Option("--out", help="Memory directory to write.")],
    encoder: EncoderOption = "pixels",
    split: Annotated[str | None, typer.Option(help="Only this split (project layout).")] = None,
    no_successes: Annotated[
        bool,
        typer.Option(
            "--no-successes", help="The paper's failure memory alone (no success memory, no contrast)."
        ),
    ] = False,
    cache_dir: CacheOption = None,
    device: DeviceOption = None,
) -> None:
    """Build a failure memory (Algorithm 1) from the failure trajectories of DATA, and a success memory."""
    from robofailring.pipeline import BuildMemoryConfig, build_memory

    try:
        memory, stats = build_memory(
            BuildMemoryConfig(
                data=data,
                encoder=encoder,
                out=out,
                split=split,
                cache_dir=cache_dir,
                device=device,
                successes=not no_successes,
            )
        )
    except RoboFailRingError as error:
        exit_with_error(error)
    typer.echo(
        f"memory {out}: {len(memory)} entries ({memory.dim}-d, encoder {memory.encoder}) from "
        f"{stats.failures} failure trajectories over {len(memory.tasks)} tasks; "
        f"{stats.ignored_non_failures} non-failures ignored, {len(stats.skipped_views)} views skipped (< 2 frames)"
    )
    if memory.successes is not None:
        typer.echo(
            f"success memory: {len(memory.successes)} frames of {len(memory.successes.runs)} success views "
            f"over {len(memory.successes.tasks)} tasks"
        )
    for skipped in stats.skipped_views[:10]:
        typer.echo(f"  skipped {skipped['trajectory']} view {skipped['view']}: {skipped['frames']} frame(s)")


@app.command("detect")
def detect_cmd(
    trajectory: Annotated[Path, typer.Argument(help="One episode folder.")],
    memory: Annotated[Path, typer.Option("--memory", help="Memory directory.")],
    delta: Annotated[
        float | None, typer.Option(help="Threshold δ (default: the memory's calibrated δ, else 0.92).")
    ] = None,
    k: Annotated[int, typer.Option(help="Neighbours retrieved per query.")] = 5,
    score: ScoreOption = None,
    gamma: GammaOption = None,
    task: Annotated[str | None, typer.Option(help="Task name, when the folder name does not say.")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print the full trace as one JSON object.")] = False,
    leave_one_out: Annotated[
        bool, typer.Option("--leave-one-out", help="Hide the trajectory's own episode from the memory.")
    ] = False,
    encoder: Annotated[str | None, typer.Option(help="Encoder spec (default: the memory's).")] = None,
    cache_dir: CacheOption = None,
    device: DeviceOption = None,
) -> None:
    """Replay one trajectory through the detector and say if and when it fires."""
    from robofailring.pipeline import DetectConfig, detect

    try:
        trace = detect(
            DetectConfig(
                trajectory=trajectory,
                memory=memory,
                delta=delta,
                k=k,
                score=score,
                gamma=gamma,
                task=task,
                leave_one_out=leave_one_out,
                encoder=encoder,
                cache_dir=cache_dir,
                device=device,
            )
        )
    except RoboFailRingError as error:
        exit_with_error(error)
    for view, count in trace.truncated_views.items():
        typer.secho(
            f"note: view {view} has {trace.length + count} frames; the last {count} are not scored "
            f"(views are scored in step up to the shortest one, L = {trace.length})",
            fg=typer.colors.YELLOW,
            err=True,
        )
    if trace.skipped_views:
        typer.secho(
            f"note: views with fewer than 2 frames skipped: {', '.join(trace.skipped_views)}", err=True
        )
    if as_json:
        json.dump(trace.to_dict(), sys.stdout)
        sys.stdout.write("\n")
        return
    rule = trace.rule
    typer.echo(
        f"task {trace.task}, L = {trace.length} frames, rule {rule.value}: {rule.score_name} ≥ "
        f"{rule.symbol} = {trace.threshold:.3f}, K = {trace.k}"
    )
    contrasts = trace.contrast
    for view in trace.views:
        line = f"  {view:>10}: max S⁻_t = {float(np.nanmax(trace.similarity[view])):.3f}"
        if view in trace.success_similarity:
            line += f", max C_t = {float(np.nanmax(contrasts[view])):.3f}"
        typer.echo(line)
    if trace.t_det is None:
        typer.echo("no failure detected")
    else:
        fired_view = trace.detected_view
        assert fired_view is not None
        top = trace.neighbors(fired_view, trace.t_det)[0]
        fired_score = float(trace.scores[fired_view][trace.t_det])
        typer.echo(
            f"FAILURE detected at frame {trace.t_det}/{trace.length} in view {fired_view} "
            f"({rule.value} rule: {rule.score_name} = {fired_score:.3f}, S⁻_t = {top.similarity:.3f}); nearest memory entry {top.entry.task}/{top.entry.episode} "
            f"[{top.entry.view}] {top.entry.symbol}: {top.entry.description}"
        )


@app.command("calibrate")
def calibrate_cmd(
    data: Annotated[Path, typer.Argument(help="Dataset holding success trajectories of the memory's tasks.")],
    memory: Annotated[Path, typer.Option("--memory", help="Memory directory; δ is stored in its manifest.")],
    target_fpr: Annotated[float, typer.Option("--target-fpr", help="False-positive rate to allow.")] = 0.05,
    split: Annotated[str | None, typer.Option(help="Successes of this split (project layout).")] = "train",
    cache_dir: CacheOption = None,
    device: DeviceOption = None,
) -> None:
    """Set δ and γ (split conformal) for a target false-positive rate on success runs; detect then uses them."""
    from robofailring.evaluation import CalibrateConfig, calibrate

    try:
        result = calibrate(
            CalibrateConfig(
                data=data,
                memory=memory,
                target_fpr=target_fpr,
                split=split,
                cache_dir=cache_dir,
                device=device,
            )
        )
    except (RoboFailRingError, ValueError) as error:
        exit_with_error(error)
    typer.echo(
        f"δ = {result.delta:.6f} (paper rule) for encoder {result.encoder}: FPR {100 * result.achieved_fpr:.1f} % on "
        f"{result.successes} success runs (target {100 * result.target_fpr:.1f} %); stored in {memory}/manifest.json"
    )
    if result.gamma is not None and result.gamma_achieved_fpr is not None:
        typer.echo(
            f"γ = {result.gamma:.6f} (contrast rule): FPR {100 * result.gamma_achieved_fpr:.1f} % on the same runs, "
            "each scored with its own episode left out of the success memory"
        )


def main() -> None:
    app()


if __name__ == "__main__":
    main()
