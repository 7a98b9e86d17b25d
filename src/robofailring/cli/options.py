"""Command-line options and messages shared by every verb (each option is declared once, here).

The verbs live in `robofailring.cli.verbs` (the library's) and `rfr_viz.cli.*` (those that record);
`rfr_viz.cli.app` assembles them into the one `robofailring` command (docs/architecture.md).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Final

import typer

from robofailring.data.model import Skipped
from robofailring.detection.band import BAND_KINDS, BAND_SCOPES, DEFAULT_BAND, DEFAULT_BAND_SCOPE
from robofailring.detection.config import DEFAULT_DETECTOR, DetectorConfig
from robofailring.detection.rules import RULES
from robofailring.detection.stored import given_thresholds
from robofailring.detection.view_bands import DEFAULT_FUSION, FUSIONS
from robofailring.errors import SettingError
from robofailring.extras import require
from robofailring.memory.recipe import DEFAULT_RECIPE, MemoryRecipe
from robofailring.memory.references import ReferenceCheck

if TYPE_CHECKING:
    from robofailring.explain.vlm import VLMConfig


EncoderOption = Annotated[
    str,
    typer.Option(
        "--encoder",
        help="`pixels` (weight-free), `open_clip:<model>[:<pretrained tag or checkpoint path>]` or `trained:<DIR>`.",
    ),
]
CacheOption = Annotated[
    Path | None, typer.Option("--cache-dir", help="Embedding cache folder (default ~/.cache/robofailring).")
]
RayOption = Annotated[
    str | None,
    typer.Option(
        "--ray",
        metavar="ADDRESS",
        help="Decode and encode the frames on a Ray cluster (Ray Data): `auto` (the running one), `local` (a "
        "new one on this machine) or `ray://host:port`; same embeddings, same cache (docs/ray.md).",
    ),
]
DeviceOption = Annotated[
    str | None, typer.Option("--device", help="torch device (default: cuda if available).")
]
RuntimeOption = Annotated[
    str | None,
    typer.Option(
        "--runtime",
        help="What runs the encoder's network: `torch`, or its ONNX export (made once, cached by checkpoint "
        "digest): `onnx` (fp32) or `onnx-int8` through ONNX Runtime, `openvino-int8` (static int8 on OpenVINO, "
        "the fastest on a CPU; the openvino extra). Default: the spec's own `@runtime`, else torch.",
    ),
]
StrideOption = Annotated[
    int,
    typer.Option(
        "--stride",
        help="Score every Nth frame of long episodes (I_0 stays frame 0; t_det and T_s in original frames).",
    ),
]
BandOption = Annotated[
    str,
    typer.Option(
        "--band",
        help=f"Time-indexed thresholds, one of {', '.join(BAND_KINDS)}: the contrast and novelty scores are "
        "corrected by the calibration successes' mean (shift) or mean and spread (norm) at the same frame "
        f"index before their peak is calibrated; none: one threshold (default {DEFAULT_BAND}).",
    ),
]
BandScopeOption = Annotated[
    str,
    typer.Option(
        "--band-scope",
        help=f"Which runs a band is fitted on, one of {', '.join(BAND_SCOPES)}: pooled, every task's calibration "
        "runs together; task, each task with enough runs its own (the others the pooled band) "
        f"(default {DEFAULT_BAND_SCOPE}).",
    ),
]
FusionOption = Annotated[
    str,
    typer.Option(
        "--fusion",
        help=f"How the views meet the threshold, one of {', '.join(FUSIONS)}: max, the paper's, fires when any "
        "view reaches it, every view corrected by one band (of the max over views); per-view corrects each "
        f"view by a band of its own calibration scores first; per-modality one band for the cameras and one for the "
        f"robot's signals (default {DEFAULT_FUSION}).",
    ),
]
LabelsOption = Annotated[
    Path | None,
    typer.Option(
        "--labels",
        help="Outcome and failure symbol per episode: a JSON list or CSV of episode_index, outcome, symbol "
        "and optionally task and description (`episode` names an episode folder, an HDF5 demo or episode "
        "file; a failure without a symbol is 'a failure (type not labelled)').",
    ),
]
VocabularyOption = Annotated[
    Path | None,
    typer.Option(
        "--vocabulary",
        help="Your own failure symbols beyond Table 5: a JSON or YAML file of `symbols` (symbol: the words "
        "for its cause) and optional `stages` (number: words); kept in the memory's folder.",
    ),
]
VLMUrlOption = Annotated[
    str | None,
    typer.Option(
        "--vlm-url",
        help="Base URL of an OpenAI-compatible server (e.g. http://localhost:11434/v1) to ask about the "
        "report; key from $ROBOFAILRING_VLM_API_KEY.",
    ),
]
VLMModelOption = Annotated[
    str | None, typer.Option("--vlm-model", help="Model the VLM server serves (with --vlm-url).")
]
ScoreOption = Annotated[
    str | None,
    typer.Option(
        "--score",
        help="Scoring rule: "
        + " or ".join(f"`{rule.name}` ({rule.formula} ≥ {rule.symbol})" for rule in RULES.values())
        + "; default per task: contrast with success and failure runs, novelty with success runs only, "
        "paper with failure runs only.",
    ),
]
GammaOption = Annotated[
    float | None,
    typer.Option(help="Contrast threshold γ (default: the memory's calibrated γ, else 0)."),
]
EtaOption = Annotated[
    float | None,
    typer.Option(help="Novelty threshold η (default: the memory's calibrated η, else 0.1)."),
]


#: Lines of one list (inputs not read, trajectories skipped) printed before one line counts the rest.
SHOWN_LINES: Final[int] = 20


def report_skipped(skipped: Sequence[Skipped], *, kept_in: str | None = None) -> None:
    """One summary line of what the loaders did not read, then the first `SHOWN_LINES` with their reason
    (stderr); `kept_in`: the output listing them all, named in the line that counts the rest."""
    if not skipped:
        return
    typer.secho(
        f"note: {len(skipped):,} folder(s)/file(s) under the data were not read:",
        fg=typer.colors.YELLOW,
        err=True,
    )
    echo_first([f"  {item.path}: {item.reason}" for item in skipped], kept_in=kept_in, err=True)


def report_skipped_runs(skipped: Sequence[tuple[str, str]], *, kept_in: str | None = None) -> None:
    """The trajectories a verb skipped, `skipped <key>: <reason>`, the first `SHOWN_LINES` of them."""
    echo_first([f"skipped {key}: {reason}" for key, reason in skipped], kept_in=kept_in)


def echo_first(lines: Sequence[str], *, kept_in: str | None = None, err: bool = False) -> None:
    """The first `SHOWN_LINES` of `lines`, then one line counting the rest (10,000 skipped episodes are not
    10,000 lines), naming `kept_in`, where they are all, when there is such an output."""
    for line in lines[:SHOWN_LINES]:
        typer.echo(line, err=err)
    if len(lines) > SHOWN_LINES:
        where = f" (all in {kept_in})" if kept_in else ""
        typer.echo(f"  … and {len(lines) - SHOWN_LINES:,} more{where}", err=err)


SuccessStepOption = Annotated[
    float,
    typer.Option(
        "--success-step",
        help="Keep a success frame only when its cosine to the last kept frame of its run is below "
        "1 - STEP (0 keeps every frame).",
    ),
]
FailureFramesOption = Annotated[
    str | None,
    typer.Option(
        "--failure-frames",
        help="`dense`: each failure run's frames from its onset on (all when it is not known), thinned like "
        "the success memory (--success-step), so a neighbour shows the moment of the past failure that "
        "matches; `end`: the paper's memory, one (I_0 ‖ I_end) entry per failure view. Default: dense "
        "(growing a memory with --add-to keeps its own).",
    ),
]
PairingOption = Annotated[
    str | None,
    typer.Option(
        "--pairing",
        help="How a first and a current frame become one memory vector: `change`, the first frame at half "
        "weight beside what changed since it, norm([½ z_0 ‖ z_t − z_0]) (holds up under new lighting, colours "
        "and cameras); `concat`, the paper's norm([z_0 ‖ z_t]). Default: change (growing a memory with "
        "--add-to keeps its own).",
    ),
]
ModalityOption = Annotated[
    str,
    typer.Option(
        "--modality",
        help="What the detector judges by: `both`, the cameras and the robot's signals fused as views (where the "
        "memory has signals); `cameras` alone; `signals` alone. Thresholds calibrated for one are not used for "
        "another (calibrate with the same --modality).",
    ),
]
SignalsOption = Annotated[
    str | None,
    typer.Option(
        "--signals",
        help="The robot's own signals (joint state, gripper, end-effector pose, commanded actions) as a second "
        "modality beside the cameras, scored as the view `signals`: `auto`, every state and action signal the "
        "data has (docs/data.md); `none`, the cameras alone; or signal names separated by commas. Default: "
        "auto (growing a memory with --add-to keeps its own).",
    ),
]
SignalFeaturesOption = Annotated[
    str | None,
    typer.Option(
        "--signal-features",
        help="Features derived from the robot's signals and added to them (docs/signals.md): `change`, each "
        "dimension's change over the last frame; `events`, for each step-like dimension (a gripper) its jumps "
        "so far and the frames since the last; both separated by a comma, or `none`. Default: change,events "
        "(growing a memory with --add-to keeps its own).",
    ),
]
DataRootOption = Annotated[
    Path | None,
    typer.Option(
        "--data-root",
        help="Where the memory's dataset is now, when it moved since the memory was built "
        "(its images are looked up there).",
    ),
]


DETECTOR_DEFAULTS: Final[DetectorConfig] = DEFAULT_DETECTOR  # the detector options' defaults (e.g. --k)
RECIPE_DEFAULTS: Final[MemoryRecipe] = DEFAULT_RECIPE  # the memory options' defaults (e.g. --success-step)


def detector_config(
    memory: Path | None,
    *,
    encoder: str | None = None,
    device: str | None = None,
    runtime: str | None = None,
    cache_dir: Path | None = None,
    data_root: Path | None = None,
    k: int = DETECTOR_DEFAULTS.k,
    score: str | None = None,
    delta: float | None = None,
    gamma: float | None = None,
    eta: float | None = None,
    modality: str = DETECTOR_DEFAULTS.modality,
) -> DetectorConfig:
    """The `DetectorConfig` of a verb's detector options: --memory, --encoder, --device, --runtime, --cache-dir,
    --data-root, --k, --score, each rule's threshold by its option (--delta, --gamma, --eta), --modality."""
    return DetectorConfig(
        memory=memory,
        encoder=encoder,
        device=device,
        runtime=runtime,
        cache_dir=cache_dir,
        data_root=data_root,
        k=k,
        rule=score,
        thresholds=given_thresholds(None, delta=delta, gamma=gamma, eta=eta),
        modality=modality,
    )


def memory_recipe(
    encoder: str = RECIPE_DEFAULTS.encoder,
    *,
    failure_frames: str | None = None,
    pairing: str | None = None,
    success_step: float | None = None,
    signals: str | None = None,
    signal_features: str | None = None,
) -> MemoryRecipe:
    """The `MemoryRecipe` of a verb's memory options (--encoder, --failure-frames, --pairing,
    --success-step, --signals, --signal-features); the recipe's defaults for those left out."""
    return MemoryRecipe.chosen(
        encoder,
        failure_frames=failure_frames,
        pairing=pairing,
        success_step=success_step,
        signals=signals,
        signal_features=signal_features,
    )


def print_notes(notes: Sequence[str]) -> None:
    """Warnings and notes a job returned, one line each on stderr."""
    for note in notes:
        typer.secho(note, fg=typer.colors.YELLOW, err=True)


def warn_missing_references(memory: Path, check: ReferenceCheck | None) -> None:
    """One warning line when a memory's reference images cannot be found (nothing silent)."""
    if check is not None and not check.ok:
        typer.secho(
            f"warning: memory {memory}: "
            + check.summary(
                hint="; if the dataset moved, pass --data-root DIR (see `robofailring memory-info`)"
            ),
            fg=typer.colors.YELLOW,
            err=True,
        )


def vlm_config(url: str | None, model: str | None) -> VLMConfig | None:
    """The VLM to ask, from --vlm-url and --vlm-model (both or neither: a SettingError otherwise)."""
    from robofailring.explain.vlm import VLMConfig

    if url is None or model is None:
        if url is not None or model is not None:
            raise SettingError("--vlm-url and --vlm-model go together: give both or neither")
        return None
    require("vlm")  # before any work: the VLM is asked once the detections are made
    return VLMConfig(url=url, model=model)


TaskOption = Annotated[
    str | None,
    typer.Option(
        help="Task of episodes whose names do not say it (an episode folder, video episodes); "
        "replay and compare on a dataset root keep only this task."
    ),
]
ViewsOption = Annotated[
    str | None,
    typer.Option(
        "--views",
        help="Views to use, in order: `a,b` picks views; `src=name` renames one (a camera, an HDF5 image key); "
        "default: every view the data has.",
    ),
]
MemoryOption = Annotated[Path, typer.Option("--memory", help="Memory directory.")]
DeltaOption = Annotated[
    float | None,
    typer.Option("--delta", help="Threshold δ (default: the memory's calibrated δ, else 0.92)."),
]
KOption = Annotated[int, typer.Option("--k", help="Neighbours retrieved per query.")]
MemoryEncoderOption = Annotated[
    str | None, typer.Option("--encoder", help="Encoder spec (default: the memory's).")
]
ReferenceEncoderOption = Annotated[
    str | None,
    typer.Option(
        "--encoder",
        help="Encoder spec: the reference's without --memory (default pixels), else the memory's.",
    ),
]
LeaveOneOutOption = Annotated[
    bool, typer.Option("--leave-one-out", help="Hide each trajectory's own episode from the memory.")
]
FpsOption = Annotated[
    float | None,
    typer.Option(
        "--fps", help="Frame rate of the `time` timeline, 0.001–10000 (default: the data's, else 10)."
    ),
]
DataArgument = Annotated[
    Path, typer.Argument(help="Dataset root (any supported layout) or one episode folder.")
]
RecordingsOutOption = Annotated[
    Path, typer.Option("--out", help="Folder for the .rrd files (one per trajectory).")
]
TrajectoriesOption = Annotated[
    list[str] | None,
    typer.Option(
        "--trajectory", help="Only this trajectory (`<task>/<episode>` or the episode); repeatable."
    ),
]
WorkersOption = Annotated[int, typer.Option("--workers", help="Simulation processes.")]
RandomizeOption = Annotated[
    int,
    typer.Option(
        "--randomize",
        help="The trained encoder also trains on N simulated episodes of the data's tasks under random looks "
        "(object, table, tray and goal colours, light, camera shifts, object size) at the data's image size "
        "and frames, spread over every failure family and success; simulated once and cached (0: none).",
    ),
]
