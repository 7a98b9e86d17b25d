"""The jobs people run over a whole dataset: `evaluate`, `review`, `triage`, `compare-encoders` and `demo`."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from rfr_viz.cli.options import CameraCodecOption
from rfr_viz.cli.replay import warn_vlm_errors
from rfr_viz.codecs import CameraCodec
from rfr_viz.viewer.control import open_at_command, open_command
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.cli.exit_codes import finish
from robofailring.cli.groups import Declared, takes
from robofailring.cli.option_groups import (
    DATA,
    DETECTOR,
    ENCODER,
    RECIPE,
    SCORING,
    THRESHOLDS,
    VLM,
)
from robofailring.cli.options import (
    RandomizeOption,
    StrideOption,
    report_skipped,
    tested_on,
    warn_missing_references,
)
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DEFAULT_STRIDE, DetectorConfig, Scoring
from robofailring.encoders.placement import EncoderPlacement
from robofailring.explain.vlm import VLMConfig
from robofailring.memory.recipe import MemoryRecipe

app = typer.Typer(add_completion=False)  # composed into the one `robofailring` command by rfr_viz.cli.app


@app.command("evaluate")
@takes(
    data=DATA.but(
        data=Declared(
            Annotated[Path, typer.Argument(help="Dataset: the training split's failures form the memory.")]
        )
    ),
    recipe=RECIPE,
    scoring=SCORING,
    placement=ENCODER,
    detector=DETECTOR.only("memory").but(
        memory=Declared(
            Annotated[Path | None, typer.Option(help="Use this memory instead of building one.")], None
        )
    ),
    threshold_policy=THRESHOLDS,
)
def evaluate_cmd(
    data: DataSelection,
    *,
    out: Annotated[Path, typer.Option("--out", help="Folder for <name>.md, <name>.json and <name>.rrd.")],
    recipe: MemoryRecipe,
    test_data: Annotated[
        Path | None, typer.Option(help="Test on this dataset (e.g. out-of-distribution).")
    ] = None,
    test_labels: Annotated[
        Path | None,
        typer.Option(
            "--test-labels",
            help="The labels of --test-data, in the format of --labels: two LeRobot datasets both number their "
            "episodes from 0, so each needs its own.",
            show_default="--labels",
        ),
    ] = None,
    train_split: Annotated[str, typer.Option(help="Split whose failures build the memory.")] = "train",
    test_split: Annotated[str, typer.Option(help="Split to test on.")] = "test",
    detector: DetectorConfig,
    scoring: Scoring,
    placement: EncoderPlacement,
    name: Annotated[
        str,
        typer.Option(
            help="Name of this evaluation: <name>.md, .json and .rrd in --out (a plain file name, no / or leading dot)."
        ),
    ] = "evaluation",
    stride: StrideOption = DEFAULT_STRIDE,
    threshold_policy: ThresholdPolicy,
    deployment_successes: Annotated[
        int,
        typer.Option(
            help="Per task, this many test success runs join the success memory (not tested); refused where a "
            "task would keep no test success run to measure its false positive rate on."
        ),
    ] = 0,
    growth: Annotated[
        str | None,
        typer.Option(
            help="Learning curve: labelled failures per task, e.g. 0,1,2,4 (0: success runs only, the novelty "
            "rule); one more evaluation each, then the full memory."
        ),
    ] = None,
    folds: Annotated[
        str | None,
        typer.Option(
            help="Also cross-validate over every labelled run: K folds, or `loo` (leave one episode out); each "
            "fold judged by a memory and thresholds of the other runs, pooled with counts (small data)."
        ),
    ] = None,
) -> None:
    """Every scoring rule side by side at one α, then the paper's tables: Recall/FPR sweep, T_s, per type and view."""
    from rfr_viz.jobs.evaluate import FoldsOutcome, evaluate
    from robofailring.evaluation.folds import FoldPlan
    from robofailring.evaluation.growth import parse_growth
    from robofailring.evaluation.job import EvaluateConfig

    outcome = evaluate(
        EvaluateConfig(
            data=data,
            out=out,
            recipe=recipe,
            memory=detector.memory,
            scoring=scoring,
            placement=placement,
            threshold_policy=threshold_policy,
            test_data=tested_on(data, test_data, test_labels),
            train_split=train_split,
            test_split=test_split,
            name=name,
            stride=stride,
            deployment_successes=deployment_successes,
            folds=FoldPlan.parse(folds) if folds is not None else None,
        ),
        growth=parse_growth(growth) if growth is not None else (),
    )
    report_skipped(outcome.result.skipped_inputs, kept_in=str(outcome.json_path))
    typer.echo(outcome.result.to_markdown())
    if isinstance(outcome, FoldsOutcome):  # the split gave no held-out evaluation: said, status 3
        typer.echo(
            f"\nwrote {outcome.markdown_path} and {outcome.json_path}\nreport for a browser: {outcome.report}"
        )
        warning = f"warning: no held-out evaluation ({outcome.result.held_out}); written: the cross-validation alone"
        typer.secho(warning, fg=typer.colors.YELLOW, err=True)
        return finish(skipped=1)
    typer.echo(
        f"\nwrote {outcome.markdown_path}, {outcome.json_path} and {outcome.recording} "
        f"(open with: {open_command(outcome.recording)})"
    )
    typer.echo(f"report for a browser: {outcome.report}")
    finish(skipped=outcome.skipped)  # listed in the table


@app.command("review")
@takes(
    data=DATA.only("data", "views").but(
        data=Declared(Annotated[Path, typer.Option("--data", help="The dataset that evaluation tested on.")])
    ),
    detector=DETECTOR.only("memory", "score", "cache_dir", "device", "data_root", *SCORING.options()).but(
        memory=Declared(
            Annotated[
                Path | None,
                typer.Option(help="Memory directory.", show_default="the memory the evaluation used"),
            ],
            None,
        )
    ),
    vlm=VLM,
)
def review_cmd(
    evaluation: Annotated[Path, typer.Argument(help="The <name>.json written by `robofailring evaluate`.")],
    *,
    data: DataSelection,
    kind: Annotated[str, typer.Option(help="`false-alarms` or `misses`.")] = "false-alarms",
    out: Annotated[Path, typer.Option("--out", help="Folder for the recordings.")] = Path(
        "recordings/review"
    ),
    camera_codec: CameraCodecOption = CameraCodec.AUTO,
    detector: DetectorConfig,
    vlm: VLMConfig | None,
    write_labels: Annotated[
        Path | None,
        typer.Option(
            "--write-labels",
            help="Instead of recordings, write this labels CSV: one row per false alarm and per miss (the "
            "detector's outcome, the nearest failure's symbol, frame and score) with empty outcome/symbol/"
            "description columns to fill, then grow the memory with `build-memory --labels FILE --add-to`.",
        ),
    ] = None,
) -> None:
    """Replay only the false alarms (or the misses) of an evaluation, each recording focused on the moment."""
    from rfr_viz.jobs.review import ReviewConfig, review, write_review_labels

    config = ReviewConfig(
        evaluation=evaluation,
        data=data,
        kind=kind,
        out=out,
        detector=detector,
        camera_codec=camera_codec,
        vlm=vlm,
        write_labels=write_labels,
    )
    if write_labels is not None:
        written = write_review_labels(config)
        report_skipped(written.skipped_inputs)
        left = (
            f"{written.unlabelled} of its {written.total} row(s) to label (fill in outcome, symbol or description)"
            if written.unlabelled
            else f"all {written.total} row(s) labelled"
        )
        typer.echo(
            f"wrote {written.path}: {left}, then: robofailring build-memory {data.root} --labels {written.path} "
            "--add-to MEMORY"
        )
        return
    result = review(config)
    report_skipped(result.skipped_inputs)
    for memory_dir, check in result.references.items():
        warn_missing_references(memory_dir, check)
    warn_vlm_errors(result)
    if not result.recordings:
        typer.echo(f"no {kind} in {evaluation}: nothing to replay")
        return
    typer.echo(
        f"{len(result.recordings)} recording(s); each line opens one paused at the moment (or use `rerun FILE`):"
    )
    for path in result.recordings:
        typer.echo(f"  {open_at_command(path)}")
    finish(skipped=len(result.skipped_inputs))  # listed above


@app.command("compare-encoders")
@takes(
    data=DATA.only("data", "views").but(
        data=Declared(Annotated[Path, typer.Argument(help="Dataset with train/test splits.")])
    ),
    threshold_policy=THRESHOLDS.only("target_fpr"),
    recipe=RECIPE.only("failure_frames", "pairing"),
    # judged as detect judges (every scoring setting, one added later too) but by every modality: the table
    # has each encoder's cameras alone and both side by side
    scoring=SCORING.without("modality"),
    placement=ENCODER.only("cache_dir", "device"),
)
def compare_encoders_cmd(
    data: DataSelection,
    *,
    encoders: Annotated[list[str], typer.Option("--encoder", help="Encoder spec; give two or more.")],
    out: Annotated[Path, typer.Option("--out", help="Folder for memories, tables and recordings.")],
    threshold_policy: ThresholdPolicy,
    recordings: Annotated[int, typer.Option(help="Per-trajectory comparison recordings to write.")] = 3,
    recipe: MemoryRecipe,
    scoring: Scoring,
    placement: EncoderPlacement,
) -> None:
    """The same split under several encoders, each calibrated: a side-by-side table and comparison recordings."""
    from rfr_viz.jobs.compare_encoders import run_encoder_comparison
    from robofailring.jobs.compare_encoders import CompareEncodersConfig

    comparison = run_encoder_comparison(
        CompareEncodersConfig(
            data=data,
            out=out,
            encoders=tuple(encoders),
            threshold_policy=threshold_policy,
            recipe=recipe,
            scoring=scoring,
            placement=placement,
        ),
        recordings=recordings,
    )
    typer.echo(comparison.table)
    typer.echo(f"\nwrote {comparison.table_path}")
    for path in comparison.recordings:
        typer.echo(open_command(path))


@app.command("demo")
@takes(
    threshold_policy=THRESHOLDS.only("target_fpr"),
    recipe=RECIPE.only("failure_frames", "pairing"),
    placement=ENCODER.only("cache_dir"),
)
def demo_cmd(
    out: Annotated[Path, typer.Option("--out", help="Folder for everything the demo writes.")] = Path(
        "recordings/demo"
    ),
    episodes: Annotated[int, typer.Option(help="In-distribution episodes per task and kind.")] = 3,
    success_episodes: Annotated[
        int | None,
        typer.Option(
            help="In-distribution success runs per task.",
            show_default="enough that the calibration at α does not rest on its single highest success: "
            "20 per task at α = 0.05",
        ),
    ] = None,
    ood_episodes: Annotated[int, typer.Option(help="Out-of-distribution episodes per task and kind.")] = 1,
    image_size: Annotated[int, typer.Option("--image-size", help="Simulated image size in pixels.")] = 128,
    frames: Annotated[int, typer.Option(help="Frames per simulated episode.")] = 40,
    *,
    threshold_policy: ThresholdPolicy,
    data_dir: Annotated[Path | None, typer.Option(help="Where simulated datasets are cached.")] = None,
    camera_codec: CameraCodecOption = CameraCodec.AUTO,
    recipe: MemoryRecipe,
    placement: EncoderPlacement,
    randomize: RandomizeOption = 32,
    compare_encoder: Annotated[
        list[str] | None,
        typer.Option(
            "--compare-encoder",
            help="Also measure this encoder in the encoder comparison, beside the headline and pixels (repeat "
            "for more), e.g. a pretrained backbone: `timm:efficientnet_lite0:/models/lite0.pth`.",
        ),
    ] = None,
) -> None:
    """The main job on the embedded default: simulate, build the memory, calibrate, evaluate, record."""
    from rfr_viz.jobs.demo import DemoConfig, run_demo

    result = run_demo(
        DemoConfig(
            out=out,
            episodes=episodes,
            success_episodes=success_episodes,
            ood_episodes=ood_episodes,
            image_size=image_size,
            frames=frames,
            threshold_policy=threshold_policy,
            data_dir=data_dir,
            camera_codec=camera_codec,
            recipe=recipe,
            placement=placement,
            randomize=randomize,
            compare_with=tuple(compare_encoder or ()),
        ),
        say=typer.echo,
    )
    for evaluation in result.evaluations:
        typer.echo("\n" + evaluation.to_markdown())
    typer.echo("\nTables: " + ", ".join(str(p) for p in result.tables))
    typer.echo(f"Report for a browser (charts, tables, links): {result.report}")
    typer.echo("\nOpen the recordings in the Rerun viewer:")
    typer.echo(f"  {open_command(result.summary)}    # evaluation: Recall/FPR against δ, ROC, T_s histogram")
    for kind, path in result.recordings.items():
        typer.echo(f"  {open_command(path)}    # {kind}")
    typer.echo("Or open one paused at its alarm (the miss: at its highest S_t):")
    for kind, path in result.recordings.items():
        typer.echo(f"  {open_at_command(path)}    # {kind}")
    if result.comparison is not None:
        typer.echo(f"\nEncoders compared on the in-distribution test split ({result.comparison.table_path}):")
        typer.echo(result.comparison.table)
        for path in result.comparison.recordings:
            typer.echo(f"  {open_command(path)}    # the encoders side by side")
    for note in result.notes:
        typer.echo(f"note: {note}")
