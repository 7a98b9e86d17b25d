"""`open_detector`: a memory folder to a ready detector in one call, with the memory's stored calibration;
`detector_from`, the same from a `DetectorConfig` (what the jobs hold); `detector_with`, the one place a
`DetectorConfig`'s settings become a detector's (its encoder is its `EncoderPlacement.open`)."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path

from robofailring.detection.band import Band
from robofailring.detection.config import DEFAULT_K, DEFAULT_MODALITY, DetectorConfig, Scoring
from robofailring.detection.detector import FailureDetector
from robofailring.detection.rules import ScoringRule
from robofailring.detection.stored import given_thresholds
from robofailring.encoders import CachedEncoder
from robofailring.encoders.placement import EncoderPlacement
from robofailring.encoders.spec import EncoderSpec
from robofailring.memory.failure import FailureMemory


def detector_with(
    config: DetectorConfig,
    memory: FailureMemory,
    encoder: CachedEncoder,
    *,
    bands: Mapping[str, Band] | None = None,
) -> FailureDetector:
    """The detector of `config`'s K, rule, thresholds and modality on a memory and encoder in hand: the one
    place a `DetectorConfig`'s settings become a detector's. `bands`: thresholds' bands calibrated in process."""
    return FailureDetector(
        memory,
        encoder,
        thresholds=config.thresholds,
        k=config.scoring.k,
        rule=config.rule,
        bands=bands,
        modality=config.scoring.modality,
    )


def detector_from(config: DetectorConfig, *, trusted: Iterable[Path] = ()) -> FailureDetector:
    """Load `config.memory` and its encoder (or `config.encoder`, which must give the same identity), and
    return its detector at `config.thresholds` (by rule name; the memory's calibrated ones for the rest).

    `trusted`: the folders of the data a job reads, where the memory's images may also be read from
    (besides `config.data_root` and the memory's own folder; `FailureMemory.image_roots`)."""
    memory = FailureMemory.load(
        config.memory_dir,
        data_root=Path(config.data_root) if config.data_root is not None else None,
        trusted=trusted,
    )
    return detector_with(config, memory, config.placement.open(config.encoder or encoder_spec_for(memory)))


def encoder_spec_for(memory: FailureMemory) -> str:
    """The encoder spec that reproduces a memory's encoder identity (pixels or open_clip)."""
    return EncoderSpec.for_memory(memory.encoder, memory.manifest.encoder_spec)


def open_detector(
    memory_dir: str | Path,
    *,
    device: str | None = None,
    rule: ScoringRule | str | None = None,
    thresholds: Mapping[str, float] | None = None,
    delta: float | None = None,
    gamma: float | None = None,
    eta: float | None = None,
    k: int = DEFAULT_K,
    data_root: str | Path | None = None,
    encoder: str | None = None,
    cache_dir: str | Path | None = None,
    runtime: str | None = None,
    modality: str = DEFAULT_MODALITY,
) -> FailureDetector:
    """Load the memory at `memory_dir` and its encoder, and return its detector (judging by `modality`:
    `both` the cameras and the robot's signals, the `cameras` or the `signals` alone).

    Thresholds are `thresholds` by rule name (`delta`, `gamma`, `eta`: the paper, contrast and novelty
    rules'), else the memory's calibrated ones (else each rule's default: the paper's δ = 0.92, γ = 0,
    η = 0.1); the rule defaults per task (`FailureDetector.rule_for`). `encoder`
    overrides the spec the memory was built with (it must give the same identity); `data_root` is
    where the memory's images are now, when its data moved; `device` is the torch device for CLIP;
    `runtime` runs the encoder in torch or from its export (`onnx`, `onnx-int8`, `openvino-int8`; docs/runtime.md).
    """
    return detector_from(
        DetectorConfig(
            memory=Path(memory_dir),
            encoder=encoder,
            data_root=Path(data_root) if data_root is not None else None,
            rule=rule.name if isinstance(rule, ScoringRule) else rule,
            thresholds=given_thresholds(thresholds, delta=delta, gamma=gamma, eta=eta),
            scoring=Scoring(k=k, modality=modality),
            placement=EncoderPlacement(
                device=device, runtime=runtime, cache_dir=Path(cache_dir) if cache_dir is not None else None
            ),
        )
    )
