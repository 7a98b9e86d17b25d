"""Library entry points behind the CLI verbs: each takes a config and does one job."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from robofailring.data.layouts import load_dataset, load_trajectory
from robofailring.detector import DEFAULT_K, DetectionTrace, FailureDetector
from robofailring.encoders import CachedEncoder, load_encoder
from robofailring.errors import EncoderError
from robofailring.memory import BuildStats, FailureMemory
from robofailring.progress import progress_bar
from robofailring.success_memory import SuccessMemory


@dataclass(frozen=True)
class BuildMemoryConfig:
    data: Path  # dataset root of any supported layout
    encoder: str  # encoder spec, e.g. `pixels` or `open_clip:ViT-B-32:openai`
    out: Path  # memory directory to write (atomically)
    split: str | None = None  # only trajectories of this split (project layout)
    cache_dir: Path | None = None  # embedding cache (default ~/.cache/robofailring)
    device: str | None = None  # torch device for CLIP (default: cuda when available)
    successes: bool = True  # also build the success memory (contrast rule); False: the paper's memory alone


def build_memory(config: BuildMemoryConfig) -> tuple[FailureMemory, BuildStats]:
    """Build a failure memory from a dataset's failure trajectories and save it."""
    encoder = CachedEncoder(load_encoder(config.encoder, device=config.device), cache_dir=config.cache_dir)
    dataset = load_dataset(config.data)
    trajectories = (
        dataset.select(split=config.split) if config.split is not None else list(dataset.trajectories())
    )
    entries_expected = sum(len(t.views) for t in trajectories if t.symbol)
    with progress_bar(total=entries_expected, desc="encoding memory", unit="entry") as bar:
        memory, stats = FailureMemory.build(trajectories, encoder, progress=bar.update)
    if config.successes:
        with progress_bar(total=len(trajectories), desc="encoding success memory", unit="traj") as bar:
            successes = SuccessMemory.build(trajectories, encoder, progress=bar.update)
        memory.successes = successes if successes.success_runs else None  # none: the paper's memory
    memory.manifest["source"] = str(Path(config.data).resolve())
    memory.manifest["layout"] = dataset.layout
    memory.manifest["encoder_spec"] = config.encoder
    if config.split is not None:
        memory.manifest["split"] = config.split
    memory.save(config.out)
    return memory, stats


@dataclass(frozen=True)
class DetectConfig:
    trajectory: Path  # one episode folder
    memory: Path  # memory directory
    delta: float | None = None  # default: the memory's calibrated δ, else the paper's 0.92
    k: int = DEFAULT_K
    score: str | None = None  # `paper` or `contrast` (default: contrast when the memory has successes)
    gamma: float | None = None  # contrast threshold (default: the memory's calibrated γ, else 0)
    task: str | None = None  # needed when the folder name does not encode the task
    leave_one_out: bool = False  # hide the trajectory's own episode from the memory
    encoder: str | None = None  # default: the spec the memory was built with
    cache_dir: Path | None = None
    device: str | None = None


def encoder_spec_for(memory: FailureMemory) -> str:
    """The encoder spec that reproduces a memory's encoder identity (pixels or open_clip)."""
    identity = memory.encoder
    if identity.startswith("pixels"):
        return "pixels"
    spec = memory.manifest.get("encoder_spec")
    if isinstance(spec, str):
        return spec
    if ":file-" in identity:
        model = identity.split(":")[1]
        raise EncoderError(
            f"this memory was built with {identity} (a checkpoint file) and does not record where that file is; "
            f"pass --encoder open_clip:{model}:/path/to/the/same/checkpoint"
        )
    return identity


def detect(config: DetectConfig) -> DetectionTrace:
    """Run the detector over one trajectory folder."""
    memory = FailureMemory.load(config.memory)
    trajectory = load_trajectory(config.trajectory, task=config.task)
    spec = config.encoder or encoder_spec_for(memory)
    encoder = CachedEncoder(load_encoder(spec, device=config.device), cache_dir=config.cache_dir)
    detector = FailureDetector(
        memory, encoder, delta=config.delta, k=config.k, rule=config.score, gamma=config.gamma
    )
    return detector.run(trajectory, leave_one_out=config.leave_one_out)
