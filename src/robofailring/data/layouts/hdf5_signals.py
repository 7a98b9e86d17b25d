"""Signals stored in HDF5 episodes: robomimic/LIBERO/MimicGen `obs/<key>` low-dim arrays and `actions`,
ALOHA's `/observations/qpos`, `qvel`, `effort` and `/action`, each read on demand (`HDF5Signal`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np

from robofailring.data.hdf5 import hdf5_faults, open_hdf5
from robofailring.data.signals import Signal, SignalKind

#: ALOHA's 14 joint dimensions (qpos, qvel, effort, action): six arm joints and the gripper, left then right.
_ALOHA_ARM: Final[tuple[str, ...]] = (
    "waist",
    "shoulder",
    "elbow",
    "forearm_roll",
    "wrist_angle",
    "wrist_rotate",
    "gripper",
)
ALOHA_DIMS: Final[tuple[str, ...]] = tuple(
    f"{side}_{joint}" for side in ("left", "right") for joint in _ALOHA_ARM
)
#: ALOHA's signal datasets and their kinds.
ALOHA_SIGNALS: Final[dict[str, SignalKind]] = {
    "/observations/qpos": SignalKind.STATE,
    "/observations/qvel": SignalKind.STATE,
    "/observations/effort": SignalKind.STATE,
    "/action": SignalKind.ACTION,
}


@dataclass(frozen=True)
class HDF5Signal:
    """One HDF5 dataset of per-frame values, read whole when wanted (a signal is small beside its frames)."""

    file: Path
    dataset: str

    def load(self) -> np.ndarray:
        with hdf5_faults(self.file):
            item = open_hdf5(self.file).get(self.dataset)
            if item is None or not hasattr(item, "shape"):
                raise KeyError(f"no dataset {self.dataset}")
            return np.asarray(item[()])

    @property
    def reference(self) -> str:
        return f"{self.file}#{self.dataset}"


def is_signal_array(item: Any) -> bool:
    """A numeric (N,) or (N, D) dataset: per-frame values, not an image."""
    shape = getattr(item, "shape", None)
    dtype = getattr(item, "dtype", None)
    return shape is not None and len(shape) in (1, 2) and dtype is not None and np.dtype(dtype).kind in "biuf"


def hdf5_signal(file: Path, dataset: str, name: str, kind: SignalKind, dims: tuple[str, ...] = ()) -> Signal:
    return Signal(name=name, kind=kind, source=HDF5Signal(Path(file), dataset), dims=dims)


def aloha_signals(file: Path, handle: Any) -> dict[str, Signal]:
    """An ALOHA episode's qpos, qvel, effort and action (those it has), named by ALOHA's 14 joints."""
    found = {}
    for dataset, kind in ALOHA_SIGNALS.items():
        item = handle.get(dataset)
        if item is not None and is_signal_array(item):
            dims = ALOHA_DIMS if len(item.shape) == 2 and item.shape[1] == len(ALOHA_DIMS) else ()
            found[dataset.rsplit("/", 1)[-1]] = hdf5_signal(
                file, dataset, dataset.rsplit("/", 1)[-1], kind, dims
            )
    return found


def robomimic_signals(file: Path, demo: Any, name: str) -> dict[str, Signal]:
    """A robomimic demo's low-dim observations (`obs/robot0_eef_pos`, …: state) and `actions` (action)."""
    found = {}
    obs = demo.get("obs")
    for key in obs.keys() if obs is not None else ():
        if is_signal_array(obs[key]):
            found[f"obs/{key}"] = hdf5_signal(file, f"/data/{name}/obs/{key}", f"obs/{key}", SignalKind.STATE)
    actions = demo.get("actions")
    if actions is not None and is_signal_array(actions):
        found["actions"] = hdf5_signal(file, f"/data/{name}/actions", "actions", SignalKind.ACTION)
    return found
