"""The detector's options, each declared once and turned into its value in one function.

- `placement_options` (the `ENCODER` group): where an encoder runs, an `EncoderPlacement` (--device, --runtime,
  --cache-dir, --ray), taken alone by the verbs that encode but judge nothing;
- `scoring_options` (`SCORING`): how runs are scored, a `Scoring` (--k, --modality);
- `detector_options` (`DETECTOR`): what opens a detector, a `DetectorConfig` (--memory, --score and each rule's
  threshold option, --encoder, --data-root), made with the `Scoring` and `EncoderPlacement` of its parts.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Final

import typer

from robofailring.detection.config import DEFAULT_SCORING, DetectorConfig, Scoring
from robofailring.detection.rules import RULES, threshold_keys
from robofailring.detection.stored import given_thresholds
from robofailring.encoders.placement import DEFAULT_PLACEMENT, EncoderPlacement

# Where the encoder runs: EncoderPlacement

CacheOption = Annotated[
    Path | None,
    typer.Option(
        "--cache-dir",
        help="Embedding cache folder.",
        show_default="$ROBOFAILRING_CACHE, else ~/.cache/robofailring",
    ),
]
DeviceOption = Annotated[
    str | None,
    typer.Option(
        "--device", help="Where the encoder runs: cpu, cuda, cuda:N or mps.", show_default="cuda if available"
    ),
]
RuntimeOption = Annotated[
    str | None,
    typer.Option(
        "--runtime",
        help="What runs the encoder's network: `torch`, or its ONNX export (made once, cached by checkpoint "
        "digest): `onnx` (fp32) or `onnx-int8` through ONNX Runtime, `openvino-int8` (static int8 on OpenVINO, "
        "the fastest on a CPU; the openvino extra).",
        show_default="the spec's own `@runtime`, else torch",
    ),
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


def placement_options(
    cache_dir: CacheOption = DEFAULT_PLACEMENT.cache_dir,
    device: DeviceOption = DEFAULT_PLACEMENT.device,
    runtime: RuntimeOption = DEFAULT_PLACEMENT.runtime,
    ray: RayOption = DEFAULT_PLACEMENT.ray,
) -> EncoderPlacement:
    """--cache-dir, --device, --runtime and --ray as one `EncoderPlacement`."""
    return EncoderPlacement(device=device, runtime=runtime, cache_dir=cache_dir, ray=ray)


# How runs are scored: Scoring, and what opens a detector: DetectorConfig

MemoryOption = Annotated[Path | None, typer.Option("--memory", help="Memory directory.")]
KOption = Annotated[int, typer.Option("--k", help="Neighbours retrieved per query.")]
ScoreOption = Annotated[
    str | None,
    typer.Option(
        "--score",
        help="Scoring rule: "
        + " or ".join(f"`{rule.name}` ({rule.formula} ≥ {rule.symbol})" for rule in RULES.values())
        + ".",
        show_default="per task: contrast with success and failure runs, novelty with success runs only, paper "
        "with failure runs only",
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
MemoryEncoderOption = Annotated[
    str | None, typer.Option("--encoder", help="Encoder spec.", show_default="the memory's")
]
DataRootOption = Annotated[
    Path | None,
    typer.Option(
        "--data-root",
        help="Where the memory's dataset is now, when it moved since the memory was built "
        "(its images are looked up there).",
    ),
]


def scoring_options(
    k: KOption = DEFAULT_SCORING.k, modality: ModalityOption = DEFAULT_SCORING.modality
) -> Scoring:
    """--k and --modality as one `Scoring`."""
    return Scoring(k=k, modality=modality)


def detector_options(
    memory: MemoryOption = None,
    scoring: Scoring = DEFAULT_SCORING,
    score: ScoreOption = None,
    encoder: MemoryEncoderOption = None,
    data_root: DataRootOption = None,
    placement: EncoderPlacement = DEFAULT_PLACEMENT,
    **thresholds: float | None,
) -> DetectorConfig:
    """--memory, --score, each rule's threshold option (`--delta`, `--gamma`, `--eta`), --encoder and --data-root
    as one `DetectorConfig`, with the `Scoring` and `EncoderPlacement` their own options made."""
    return DetectorConfig(
        memory=memory,
        encoder=encoder,
        data_root=data_root,
        rule=score,
        thresholds=given_thresholds(None, **thresholds),
        scoring=scoring,
        placement=placement,
    )


def _with_rule_thresholds(build: Callable[..., DetectorConfig]) -> inspect.Signature:
    """`build`'s signature with its `**thresholds` as one option per registered rule, after `--score`: the rule
    gives the option's name (`--<threshold_key>`) and help, so a new rule needs no line here."""
    options = [
        inspect.Parameter(
            rule.threshold_key,
            inspect.Parameter.KEYWORD_ONLY,
            default=None,
            annotation=Annotated[
                float | None,
                typer.Option(
                    f"--{rule.threshold_key}", help=rule.threshold_help, show_default=rule.threshold_default
                ),
            ],
        )
        for rule in RULES.values()
    ]
    signature = inspect.signature(build, eval_str=True)
    parameters = []
    for parameter in signature.parameters.values():
        if parameter.kind is inspect.Parameter.VAR_KEYWORD:
            continue
        parameters.append(parameter.replace(kind=inspect.Parameter.KEYWORD_ONLY))
        if parameter.name == "score":
            parameters += options
    return signature.replace(parameters=parameters)


detector_options.__signature__ = _with_rule_thresholds(detector_options)  # type: ignore[attr-defined]

#: Each registered rule's threshold option (`delta`, `gamma`, `eta`), for the verbs that judge by a memory's own.
RULE_THRESHOLDS: Final[tuple[str, ...]] = threshold_keys()
#: The options that choose a rule and its thresholds, for the verbs that set them (calibrate, evaluate).
RULE_CHOICE: Final[tuple[str, ...]] = ("score", *RULE_THRESHOLDS)
