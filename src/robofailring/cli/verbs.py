"""The library's verbs (generate, build-memory, detect, calibrate, memory-info, train-encoder) as one typer app.

Thin: each parses, builds a config and calls one library function; the options that make one value come in
groups (`robofailring.cli.option_groups`). `rfr_viz.cli.app` composes this app with the recording verbs into
the one `robofailring` command.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from robofailring.calibration.policy import ThresholdPolicy
from robofailring.cli.exit_codes import ErrorMappingGroup, finish
from robofailring.cli.groups import Declared, takes
from robofailring.cli.option_groups import DATA, DETECTOR, ENCODER, RECIPE, SCORING, THRESHOLDS, VLM
from robofailring.cli.options import (
    LeaveOneOutOption,
    RandomizeOption,
    StrideOption,
    WorkersOption,
    print_notes,
    report_skipped,
    warn_missing_references,
)
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DEFAULT_STRIDE, DetectorConfig, Scoring
from robofailring.encoders.placement import EncoderPlacement
from robofailring.errors import SettingError
from robofailring.explain.vlm import VLMConfig
from robofailring.memory.recipe import MemoryRecipe

app = typer.Typer(  # unnamed, so rfr_viz.cli.app merges its verbs into the one `robofailring` command
    cls=ErrorMappingGroup,  # every verb: a one-line error and its exit status (robofailring.cli.exit_codes)
    help="The library's verbs of RoboFailRing (the full command is `robofailring`).",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    add_completion=False,
)


@app.command("generate")
def generate_cmd(
    out: Annotated[Path, typer.Option("--out", help="Dataset folder to write (the project's layout).")],
    tasks: Annotated[
        list[str] | None, typer.Option("--tasks", help="Tasks to run (repeatable).", show_default="all")
    ] = None,
    episodes: Annotated[
        int, typer.Option(help="Episodes per task and kind (failure family or success).")
    ] = 2,
    success_episodes: Annotated[
        int | None, typer.Option(help="Success episodes per task.", show_default="--episodes")
    ] = None,
    seed: Annotated[int, typer.Option(help="Base seed: the same seed gives identical images.")] = 0,
    look: Annotated[
        str,
        typer.Option(
            "--look",
            help="`in` (the in-distribution look), `ood` (out-of-distribution palettes, light, cameras, "
            "sizes: the `ood` split) or `random` (colours, light, cameras and sizes drawn from wide ranges).",
        ),
    ] = "in",
    ood: Annotated[bool, typer.Option("--ood", help="The same as --look ood.")] = False,
    image_size: Annotated[
        int, typer.Option("--image-size", help="Square image size in pixels (16 to 1024).")
    ] = 128,
    frames: Annotated[int, typer.Option(help="Frames per episode.")] = 40,
    workers: WorkersOption = 2,
) -> None:
    """Simulate the embedded FailGen (PyBullet Panda): failures injected by perturbing keyframes, plus successes."""
    from robofailring.sim import TASKS, GenerateConfig, describe_dataset, simulate

    config = GenerateConfig(
        out=out,
        tasks=tuple(tasks) if tasks else TASKS,
        episodes=episodes,
        success_episodes=success_episodes,
        seed=seed,
        ood=ood,
        look=look,
        image_size=image_size,
        frames=frames,
        workers=workers,
    )
    typer.echo(describe_dataset(simulate(config)))


@app.command("build-memory")
@takes(
    data=DATA.but(
        data=Declared(
            Annotated[Path, typer.Argument(help="Dataset root (any supported layout; an HDF5 file).")]
        )
    ),
    recipe=RECIPE,
    placement=ENCODER,
)
def build_memory_cmd(
    data: DataSelection,
    *,
    out: Annotated[Path | None, typer.Option("--out", help="Memory directory to write.")] = None,
    add_to: Annotated[
        Path | None,
        typer.Option(
            "--add-to",
            help="Grow this memory in place with DATA's runs (same encoder; episodes it holds are refused) "
            "instead of writing a new one with --out.",
        ),
    ] = None,
    split: Annotated[str | None, typer.Option(help="Only this split (project layout).")] = None,
    no_successes: Annotated[
        bool,
        typer.Option(
            "--no-successes", help="The paper's failure memory alone (no success memory, no contrast)."
        ),
    ] = False,
    recipe: MemoryRecipe,
    placement: EncoderPlacement,
) -> None:
    """Build a failure memory (Algorithm 1) from the failure trajectories of DATA, and a success memory."""
    from robofailring.jobs.build_memory import BuildMemoryConfig, build_memory
    from robofailring.memory.info import failure_memory_text

    if (out is None) == (add_to is None):
        raise SettingError(
            "pass --out DIR (build a new memory) or --add-to DIR (grow one), exactly one of them"
        )
    target = out if out is not None else add_to
    assert target is not None
    memory, stats = build_memory(
        BuildMemoryConfig(
            data=data,
            out=target,
            recipe=recipe,
            placement=placement,
            split=split,
            success_memory=not no_successes,
            add_to=add_to is not None,
        )
    )
    typer.echo(
        f"memory {target}: {len(memory)} entries ({memory.dim}-d, encoder {memory.encoder}) from "
        f"{stats.failures} failure trajectories over {sum(map(memory.has_failures, memory.tasks))} tasks; "
        f"{stats.ignored_non_failures} non-failures ignored"
        + (
            f"; {stats.unlabelled} unlabelled run(s) not used (give their outcome with --labels)"
            if stats.unlabelled
            else ""
        )
    )
    typer.echo(f"failure memory: {failure_memory_text(memory)}")
    if memory.successes is not None:
        typer.echo(
            f"success memory: {len(memory.successes)} frames kept of {memory.successes.offered} offered "
            f"(thinning step {recipe.success_step:g}), {memory.successes.success_runs} success views and "
            f"{len(memory.successes.runs) - memory.successes.success_runs} failure starts over "
            f"{len(memory.successes.tasks)} tasks"
        )
    if stats.skipped_views or stats.skipped_inputs:
        typer.echo(
            f"skipped: {len(stats.skipped_views)} view(s) with < 2 frames, "
            f"{len(stats.skipped_inputs)} folder(s)/file(s) not read"
        )
    for skipped in stats.skipped_views[:10]:
        typer.echo(f"  skipped {skipped['trajectory']} view {skipped['view']}: {skipped['frames']} frame(s)")
    report_skipped(stats.skipped_inputs)
    for note in stats.notes:
        typer.secho(f"note: {note}", fg=typer.colors.YELLOW, err=True)
    finish(skipped=len(stats.skipped_views) + len(stats.skipped_inputs))


@app.command("detect")
@takes(
    data=DATA.but(
        data=Declared(
            Annotated[Path, typer.Argument(help="One episode folder, or a dataset root with --trajectory.")],
            name="trajectory",
        )
    ).without("vocabulary"),
    detector=DETECTOR.without("ray"),
    vlm=VLM,
)
def detect_cmd(
    data: DataSelection,
    *,
    detector: DetectorConfig,
    as_json: Annotated[bool, typer.Option("--json", help="Print the full trace as one JSON object.")] = False,
    leave_one_out: LeaveOneOutOption = False,
    key: Annotated[
        str | None,
        typer.Option(
            "--trajectory", help="In a dataset root: this trajectory (`episode_3`, `<task>/<episode>`)."
        ),
    ] = None,
    stride: StrideOption = DEFAULT_STRIDE,
    vlm: VLMConfig | None,
) -> None:
    """Replay one trajectory through the detector and say if and when it fires."""
    from robofailring.jobs.detect import DetectConfig, run_detect

    result = run_detect(
        DetectConfig(
            data=data,
            detector=detector,
            key=key,
            leave_one_out=leave_one_out,
            stride=stride,
            vlm=vlm,
        )
    )
    skipped = [*result.trace.skipped_inputs, *result.trace.short_views]
    report_skipped(skipped)
    warn_missing_references(detector.memory_dir, result.references)
    print_notes(result.notes)
    typer.echo(result.to_json() if as_json else result.to_text())
    finish(skipped=len(skipped))  # listed above


@app.command("calibrate")
@takes(
    data=DATA.but(
        data=Declared(
            Annotated[
                Path, typer.Argument(help="Dataset holding success trajectories of the memory's tasks.")
            ]
        )
    ).without("vocabulary"),
    detector=DETECTOR.only("memory", "encoder"),  # the memory calibrated: it sets every rule's threshold
    scoring=SCORING,  # scored as detect scores
    placement=ENCODER.without("ray"),
    threshold_policy=THRESHOLDS,
)
def calibrate_cmd(
    data: DataSelection,
    *,
    detector: DetectorConfig,
    scoring: Scoring,
    placement: EncoderPlacement,
    threshold_policy: ThresholdPolicy,
    split: Annotated[str | None, typer.Option(help="Successes of this split (project layout).")] = "train",
    stride: StrideOption = DEFAULT_STRIDE,
) -> None:
    """Set every scoring rule's threshold (split conformal) at a target false-positive rate on success runs."""
    from robofailring.calibration.job import CalibrateConfig, calibrate

    result = calibrate(
        CalibrateConfig(
            data=data,
            memory=detector.memory_dir,
            encoder=detector.encoder,
            scoring=scoring,
            placement=placement,
            threshold_policy=threshold_policy,
            split=split,
            stride=stride,
        )
    )
    report_skipped(result.skipped_inputs)
    typer.echo(result.to_text(detector.memory_dir))
    finish(skipped=len(result.skipped_too_short) + len(result.skipped_inputs))


@app.command("memory-info")
@takes(
    detector=DETECTOR.only("memory", "data_root").but(
        memory=Declared(Annotated[Path, typer.Argument(help="Memory directory.")])
    )
)
def memory_info_cmd(
    detector: DetectorConfig,
    as_json: Annotated[bool, typer.Option("--json", help="Print the summary as one JSON object.")] = False,
) -> None:
    """What a memory holds: encoder, entries per task and view, threshold, data root, reference images found."""
    from robofailring.memory.info import MemoryInfo

    info = MemoryInfo.read(detector.memory_dir, data_root=detector.data_root)
    typer.echo(json.dumps(info.to_dict()) if as_json else info.to_text())
    warn_missing_references(detector.memory_dir, info.references)


@app.command("train-encoder")
@takes(
    data=DATA.but(
        data=Declared(
            Annotated[
                Path, typer.Argument(help="Dataset root (any layout); only the frames of --split are read.")
            ]
        )
    ).without("vocabulary"),
    placement=ENCODER.only("device"),
)
def train_encoder_cmd(
    data: DataSelection,
    *,
    out: Annotated[
        Path, typer.Option("--out", help="Encoder folder to write; use it as --encoder trained:DIR.")
    ],
    split: Annotated[
        str, typer.Option(help="Split to train on; a held-out split (test, ood) is refused.")
    ] = "train",
    image_size: Annotated[int, typer.Option("--image-size", help="CNN input side in pixels.")] = 64,
    epochs: Annotated[int, typer.Option(help="Passes over the training frames.")] = 10,
    seed: Annotated[
        int, typer.Option(help="The same seed, data, device and threads give the same weights.")
    ] = 0,
    init: Annotated[
        str | None,
        typer.Option(
            help="open_clip:<model>:<weights>: train a projection head on this frozen CLIP instead."
        ),
    ] = None,
    threads: Annotated[
        int | None, typer.Option(help="torch CPU threads.", show_default="half the cores")
    ] = None,
    placement: EncoderPlacement,
    randomize: RandomizeOption = 0,
    workers: WorkersOption = 2,
) -> None:
    """Train an encoder on your own runs: labels failure type × progress quarter × view, augmented."""
    from robofailring.encoders.training import TrainEncoderConfig
    from robofailring.jobs.train_encoder import TrainEncoderJob, run_train_encoder

    config = TrainEncoderConfig(
        data=data,
        out=out,
        split=split,
        image_size=image_size,
        epochs=epochs,
        seed=seed,
        init=init,
        threads=threads,
        device=placement.device,
    )
    folder = run_train_encoder(TrainEncoderJob(config, randomize=randomize, workers=workers), say=typer.echo)
    typer.echo(f"use it with: --encoder trained:{folder}")
