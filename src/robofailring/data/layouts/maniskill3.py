"""ManiSkill3 trajectories as its `RecordEpisode` wrapper writes them: `<name>.h5` beside `<name>.json`.

The JSON's `env_info.env_id` is the task and its `episodes` list each recorded episode (`episode_id`,
`success` at the end: the environment's own verdict, the outcome unless a labels file says otherwise;
a failed one carries no symbol). In the HDF5 file, `traj_<id>/obs/sensor_data/<camera>/rgb`
(N + 1, H, W, 3) uint8 is view `<camera>` (recorded with an `rgb` observation mode); the robot's
signals are `obs/agent/*` (`qpos`, `qvel`: state), `obs/extra/*` (`tcp_pose`, `is_grasped`: state;
`goal_pos`: other) and `actions` (N rows: frame t takes the action that led to it, frame 0 the first).
The environment's own state (`env_states`) and camera parameters are the simulator's, not the robot's,
and are not read. Trajectories are keyed `traj_<id>`; a folder of such files keys them `<file>/traj_<id>`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np

from robofailring.data.grounding import UNTYPED
from robofailring.data.hdf5 import HDF5Frames, hdf5_faults, is_hdf5, is_image_array, open_hdf5, row_format
from robofailring.data.layouts.folders import visible
from robofailring.data.layouts.hdf5_signals import HDF5Signal, hdf5_signal, is_signal_array
from robofailring.data.layouts.registry import Found, Layout, register
from robofailring.data.model import Outcome, Skipped, Trajectory
from robofailring.data.signals import Signal, SignalKind
from robofailring.errors import DataError

SHAPE: Final[str] = (
    "<name>.h5 + <name>.json (ManiSkill3 RecordEpisode: traj_<id>/obs/sensor_data/<camera>/rgb)"
)
_POSE: Final[tuple[str, ...]] = ("x", "y", "z", "qw", "qx", "qy", "qz")  # ManiSkill's pose: position, wxyz
_NAMED: Final[dict[str, tuple[SignalKind, tuple[str, ...]]]] = {
    "extra/tcp_pose": (SignalKind.STATE, _POSE),
    "extra/goal_pos": (SignalKind.OTHER, ("x", "y", "z")),
}


def metadata(path: Path) -> dict[str, Any] | None:
    """The JSON beside a ManiSkill3 trajectory file, when it is one (`env_info` and `episodes`)."""
    found = Path(path).with_suffix(".json")
    if not is_hdf5(path) or not found.is_file():
        return None
    try:
        meta = json.loads(found.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return None
    return meta if isinstance(meta, dict) and "env_info" in meta and "episodes" in meta else None


@dataclass(frozen=True)
class ActionsByFrame:
    """`actions` (N rows) on the N + 1 observed frames: frame t has the action that led to it."""

    source: HDF5Signal

    def load(self) -> np.ndarray:
        rows = self.source.load()
        return np.concatenate([rows[:1], rows]) if len(rows) else rows

    @property
    def reference(self) -> str:
        return self.source.reference


def _signals(path: Path, group: Any, name: str) -> dict[str, Signal]:
    found: dict[str, Signal] = {}
    for part in ("agent", "extra"):
        items = group.get(f"obs/{part}")
        for key in items.keys() if items is not None else ():
            if is_signal_array(items[key]):
                signal = f"{part}/{key}"
                kind, dims = _NAMED.get(signal, (SignalKind.STATE, ()))
                found[signal] = hdf5_signal(path, f"/{name}/obs/{signal}", signal, kind, dims)
    actions = group.get("actions")
    if actions is not None and is_signal_array(actions):
        source = ActionsByFrame(HDF5Signal(Path(path), f"/{name}/actions"))
        found["actions"] = Signal(name="actions", kind=SignalKind.ACTION, source=source)
    return found


def _file(path: Path, *, task: str | None, prefix: str) -> Found:
    meta = metadata(path)
    if meta is None:
        raise DataError(f"{path} is not a ManiSkill3 trajectory file ({SHAPE})")
    env = meta.get("env_info") or {}
    handle = open_hdf5(path)
    found: list[Trajectory] = []
    skipped: list[Skipped] = []
    for number, episode in enumerate(meta["episodes"]):
        try:
            name = f"traj_{int(episode['episode_id'])}"
        except (KeyError, TypeError, ValueError) as error:
            raise DataError(
                f"{path.with_suffix('.json')}: episode {number} has no episode_id ({error!r})"
            ) from error
        group = handle.get(name)
        cameras: Any = group.get("obs/sensor_data") if group is not None else None
        views: dict[str, HDF5Frames] = {}
        for camera in cameras.keys() if cameras is not None else ():
            rgb = cameras[camera].get("rgb")
            if rgb is not None and is_image_array(rgb):
                dataset = f"/{name}/obs/sensor_data/{camera}/rgb"
                views[camera] = HDF5Frames(path, dataset, int(rgb.shape[0]), form=row_format(handle, dataset))
        if not views:
            skipped.append(
                Skipped(path, f"{name} has no camera images (recorded without an rgb observation mode)")
            )
            continue
        success = episode.get("success")
        outcome = None if not isinstance(success, bool) else (Outcome.SUCCESS if success else Outcome.FAILURE)
        found.append(
            Trajectory(
                task=task or str(env.get("env_id") or path.stem),
                episode=f"{prefix}{name}",
                views=dict[str, Any](views),
                symbol=UNTYPED if outcome is Outcome.FAILURE else None,
                outcome=outcome,
                source=path,
                signals=_signals(path, group, name),
            )
        )
    return found, skipped


def maniskill3_trajectories(root: Path, *, task: str | None = None) -> Found:
    """Every episode of a ManiSkill3 trajectory file, or of each such file in a folder (others listed)."""
    root = Path(root)
    if root.is_file():
        with hdf5_faults(root):
            return _file(root, task=task, prefix="")
    entries = visible(root)
    files = [entry for entry in entries if metadata(entry) is not None]
    companions = {entry.with_suffix(".json") for entry in files}
    skipped = [
        Skipped(entry, f"not a ManiSkill3 trajectory file ({SHAPE})")
        for entry in entries
        if entry not in files and entry not in companions
    ]
    found: list[Trajectory] = []
    for path in files:
        with hdf5_faults(path):
            more, inside = _file(path, task=task, prefix=f"{path.stem}/" if len(files) > 1 else "")
        found += more
        skipped += inside
    return found, skipped


def _detect(root: Path) -> bool:
    if root.is_file():
        return metadata(root) is not None
    return root.is_dir() and any(metadata(entry) is not None for entry in visible(root))


LAYOUT: Final = register(
    Layout(
        name="maniskill3",
        detect=_detect,
        read=maniskill3_trajectories,
        help=f"ManiSkill3 trajectories {SHAPE}, a file or a folder of them",
        listed=11,
        detect_order=40,  # before robomimic, which reads any one HDF5 file
        reads_files=True,
    )
)

__all__ = ["LAYOUT", "maniskill3_trajectories", "metadata"]
