"""The command line's option groups, each declared once and turned into its value in one function.

- `DATA` (`data_options`): the dataset and how it is read, a `DataSelection`;
- `RECIPE` (`recipe_options`): how a memory is made, a `MemoryRecipe`;
- `ENCODER` (`placement_options`): where an encoder runs, an `EncoderPlacement`;
- `SCORING` (`scoring_options`): how runs are scored, a `Scoring` (K, modality);
- `DETECTOR` (`detector_options`): what opens a detector and decides, a `DetectorConfig`, with `SCORING` and
  `ENCODER` as its parts (their options are the detector's too; `robofailring.cli.detector_options`);
- `THRESHOLDS` (`threshold_options`): how thresholds are set, a `ThresholdPolicy`;
- `VLM` (`vlm_options`): the VLM to ask about a report, a `VLMConfig` (or None).

A verb takes the groups it needs (`robofailring.cli.groups.takes`), less the options that do not apply to it;
adding a setting to one of these values is one option here, one field there, and one line in its function.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Final

import typer

from robofailring.calibration.bands import BAND_KINDS, BAND_SCOPES, DEFAULT_BAND, DEFAULT_BAND_SCOPE
from robofailring.calibration.fusions import DEFAULT_FUSION, FUSIONS
from robofailring.calibration.policy import DEFAULT_TARGET_FPR, ThresholdPolicy
from robofailring.cli.detector_options import (
    RULE_CHOICE,
    RULE_THRESHOLDS,
    MemoryOption,
    detector_options,
    placement_options,
    scoring_options,
)
from robofailring.cli.groups import Declared, OptionGroup
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DetectorConfig, Scoring
from robofailring.encoders.placement import EncoderPlacement
from robofailring.encoders.spec import ENCODER_SPECS_HELP
from robofailring.errors import SettingError
from robofailring.explain.vlm import VLMConfig, read_api_key
from robofailring.extras import require
from robofailring.memory.recipe import DEFAULT_RECIPE, MemoryRecipe

# The data: DataSelection

DataArgument = Annotated[
    Path, typer.Argument(help="Dataset root (any supported layout) or one episode folder.")
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
        help="Views to use, in order: `a,b` picks views; `src=name` renames one (a camera, an HDF5 image key).",
        show_default="every view the data has",
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


def data_options(
    data: DataArgument,
    labels: LabelsOption = None,
    task: TaskOption = None,
    views: ViewsOption = None,
    vocabulary: VocabularyOption = None,
) -> DataSelection:
    """DATA, --labels, --task, --views and --vocabulary as one `DataSelection`."""
    return DataSelection(data, labels=labels, task=task, views=views, vocabulary=vocabulary)


# How a memory is made: MemoryRecipe

EncoderOption = Annotated[
    str,
    typer.Option(
        "--encoder",
        help=f"{ENCODER_SPECS_HELP}.",
    ),
]
FailureFramesOption = Annotated[
    str | None,
    typer.Option(
        "--failure-frames",
        help="`dense`: each failure run's frames from its onset on (all when it is not known), thinned like "
        "the success memory (--success-step), so a neighbour shows the moment of the past failure that "
        "matches; `end`: the paper's memory, one (I_0 ‖ I_end) entry per failure view.",
        show_default=f"{DEFAULT_RECIPE.failure_frames}; growing a memory with --add-to keeps its own",
    ),
]
PairingOption = Annotated[
    str | None,
    typer.Option(
        "--pairing",
        help="How a first and a current frame become one memory vector: `change`, the first frame at half "
        "weight beside what changed since it, norm([½ z_0 ‖ z_t − z_0]) (holds up under new lighting, colours "
        "and cameras); `concat`, the paper's norm(\\[z_0 ‖ z_t]).",
        show_default=f"{DEFAULT_RECIPE.pairing}; growing a memory with --add-to keeps its own",
    ),
]
SuccessStepOption = Annotated[
    float,
    typer.Option(
        "--success-step",
        help="Keep a success frame only when its cosine to the last kept frame of its run is below "
        "1 - STEP (0 keeps every frame).",
    ),
]
SignalsOption = Annotated[
    str | None,
    typer.Option(
        "--signals",
        help="The robot's own signals (joint state, gripper, end-effector pose, commanded actions) as a second "
        "modality beside the cameras, scored as the view `signals`: `auto`, every state and action signal the "
        "data has (docs/data.md); `none`, the cameras alone; or signals separated by commas, each `NAME` (all its "
        "dimensions) or `NAME:GLOB` (the dimensions the glob matches, e.g. `observation.state:gripper*`).",
        show_default=f"{DEFAULT_RECIPE.signals}; growing a memory with --add-to keeps its own",
    ),
]
SignalFeaturesOption = Annotated[
    str | None,
    typer.Option(
        "--signal-features",
        help="Features derived from the robot's signals and added to them (docs/signals.md): `change`, each "
        "dimension's change over the last frame; `events`, for each step-like dimension (a gripper) its jumps "
        "so far and the frames since the last; both separated by a comma, or `none`.",
        show_default=f"{DEFAULT_RECIPE.signal_features}; growing a memory with --add-to keeps its own",
    ),
]
SignalStartWeightOption = Annotated[
    float | None,
    typer.Option(
        "--signal-start-weight",
        help="The start state's weight in each signal vector beside what changed since (docs/signals.md), from 0 "
        "to 100: 0 leaves it out (where things were placed varies from run to run), 0.5 the weight memories built "
        "before it was a setting have.",
        show_default=f"{DEFAULT_RECIPE.signal_start_weight:g}; growing a memory with --add-to keeps its own",
    ),
]


def recipe_options(
    encoder: EncoderOption = DEFAULT_RECIPE.encoder,
    failure_frames: FailureFramesOption = None,
    pairing: PairingOption = None,
    success_step: SuccessStepOption = DEFAULT_RECIPE.success_step,
    signals: SignalsOption = None,
    signal_features: SignalFeaturesOption = None,
    signal_start_weight: SignalStartWeightOption = None,
) -> MemoryRecipe:
    """--encoder, --failure-frames, --pairing, --success-step, --signals, --signal-features and
    --signal-start-weight as one `MemoryRecipe`, which knows which were given (a memory grown keeps its own
    for the others)."""
    return MemoryRecipe.chosen(
        encoder,
        failure_frames=failure_frames,
        pairing=pairing,
        success_step=success_step,
        signals=signals,
        signal_features=signal_features,
        signal_start_weight=signal_start_weight,
    )


# How thresholds are set: ThresholdPolicy

TargetFprOption = Annotated[
    float,
    typer.Option(
        "--target-fpr",
        help="α, the false-positive rate allowed: every rule's threshold is calibrated to it (split conformal) on "
        "success runs; with too few of them an evaluation calibrates to the smallest α they allow and says no "
        "guarantee holds.",
    ),
]
BandOption = Annotated[
    str,
    typer.Option(
        "--band",
        help=f"Time-indexed thresholds, one of {', '.join(BAND_KINDS)}: every rule's score but the paper's is "
        "corrected by the calibration successes' mean (shift) or mean and spread (norm) at the same frame "
        "index before their peak is calibrated; none: one threshold.",
    ),
]
FusionOption = Annotated[
    str,
    typer.Option(
        "--fusion",
        help=f"How the views meet the threshold, one of {', '.join(FUSIONS)}: "
        + "; ".join(fusion.help for fusion in FUSIONS.values())
        + ".",
    ),
]
BandScopeOption = Annotated[
    str,
    typer.Option(
        "--band-scope",
        help=f"Which runs a band is fitted on, one of {', '.join(BAND_SCOPES)}: pooled, every task's calibration "
        "runs together; task, each task with enough runs its own (the others the pooled band).",
    ),
]


def threshold_options(
    target_fpr: TargetFprOption = DEFAULT_TARGET_FPR,
    band: BandOption = DEFAULT_BAND,
    fusion: FusionOption = DEFAULT_FUSION,
    band_scope: BandScopeOption = DEFAULT_BAND_SCOPE,
) -> ThresholdPolicy:
    """--target-fpr, --band, --fusion and --band-scope as one `ThresholdPolicy`."""
    return ThresholdPolicy(target_fpr=target_fpr, band=band, fusion=fusion, band_scope=band_scope)


# The VLM asked about a report: VLMConfig

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


def vlm_options(vlm_url: VLMUrlOption = None, vlm_model: VLMModelOption = None) -> VLMConfig | None:
    """--vlm-url and --vlm-model as the VLM to ask (both or neither: a SettingError otherwise)."""
    if vlm_url is None or vlm_model is None:
        if vlm_url is not None or vlm_model is not None:
            raise SettingError("--vlm-url and --vlm-model go together: give both or neither")
        return None
    require("vlm")  # before any work: the VLM is asked once the detections are made
    read_api_key()  # a key no HTTP header can carry is refused now, not after the detections
    return VLMConfig(url=vlm_url, model=vlm_model)


DATA: Final[OptionGroup[DataSelection]] = OptionGroup(data_options, panel="Data")
RECIPE: Final[OptionGroup[MemoryRecipe]] = OptionGroup(recipe_options, panel="Memory recipe")
ENCODER: Final[OptionGroup[EncoderPlacement]] = OptionGroup(placement_options, panel="Encoder")
SCORING: Final[OptionGroup[Scoring]] = OptionGroup(scoring_options, panel="Detector")
# --memory is required where the group is taken whole (the verbs that detect); left out, there is none
DETECTOR: Final[OptionGroup[DetectorConfig]] = OptionGroup(
    detector_options, panel="Detector", parts={"scoring": SCORING, "placement": ENCODER}
).but(memory=Declared(MemoryOption))
#: The names the verbs import with the groups (declared in `robofailring.cli.detector_options`)
__all__ = [
    "DATA",
    "DETECTOR",
    "ENCODER",
    "RECIPE",
    "RULE_CHOICE",
    "RULE_THRESHOLDS",
    "SCORING",
    "THRESHOLDS",
    "VLM",
    "data_options",
    "detector_options",
    "placement_options",
    "recipe_options",
    "scoring_options",
    "threshold_options",
    "vlm_options",
]
THRESHOLDS: Final[OptionGroup[ThresholdPolicy]] = OptionGroup(threshold_options, panel="Thresholds")
VLM: Final[OptionGroup[VLMConfig | None]] = OptionGroup(vlm_options, panel="VLM")
