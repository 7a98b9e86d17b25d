"""The detect job: one trajectory replayed through a memory's detector."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from robofailring.data.layouts import load_trajectory
from robofailring.data.model import Trajectory
from robofailring.detection.detector import DEFAULT_K, DetectionTrace, check_stride
from robofailring.detection.loader import open_detector


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
    key: str | None = None  # the trajectory to run when `trajectory` is a dataset root (`episode_3`)
    stride: int = 1  # score every stride-th frame (I_0 stays frame 0; t_det in original frames)
    labels: Path | None = None  # labels file (LeRobot): outcome and symbol per episode
    data_root: Path | None = None  # where the memory's images are now, when its data moved


def detect(config: DetectConfig) -> DetectionTrace:
    """Run the detector over one trajectory folder."""
    return detect_trajectory(config)[0]


def detect_trajectory(config: DetectConfig) -> tuple[DetectionTrace, Trajectory]:
    """`detect`, also returning the trajectory it loaded (for the report's current frame)."""
    check_stride(config.stride)
    detector = open_detector(
        config.memory,
        device=config.device,
        rule=config.score,
        delta=config.delta,
        gamma=config.gamma,
        k=config.k,
        data_root=config.data_root,
        encoder=config.encoder,
        cache_dir=config.cache_dir,
    )
    trajectory = load_trajectory(config.trajectory, task=config.task, key=config.key, labels=config.labels)
    return detector.run(trajectory, leave_one_out=config.leave_one_out, stride=config.stride), trajectory
