"""The project's own layout: a `manifest.json` (written by `robofailring generate`) listing every episode."""

from __future__ import annotations

import os
import zipfile
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Final

import numpy as np

from robofailring.bounded import read_npz
from robofailring.data.layouts.folders import aha_files
from robofailring.data.layouts.registry import Found, Layout, register
from robofailring.data.model import Outcome, Skipped, Trajectory, check_frame_rate, parse_onset_frame
from robofailring.data.signals import Signal, SignalKind
from robofailring.errors import DataError
from robofailring.jsontext import parse_json

PROJECT_MANIFEST: Final[str] = "manifest.json"
PROJECT_FORMAT: Final[str] = "robofailring-dataset"
#: The file of an episode's signals, beside its frames, as `robofailring generate` writes it.
SIGNALS_FILE: Final[str] = "signals.npz"
_POSE: Final[tuple[str, ...]] = ("x", "y", "z", "qx", "qy", "qz", "qw")
#: The signals `generate` writes there (`robofailring.sim.signals` records them), in order: name ->
#: (kind, dimension names); what a copy of an episode folder without its manifest is read by.
PROJECT_SIGNALS: Final[dict[str, tuple[str, tuple[str, ...]]]] = {
    "joint_positions": (
        "state",
        (*(f"panda_joint{joint}" for joint in range(1, 8)), "panda_finger_joint1", "panda_finger_joint2"),
    ),
    "gripper_width": ("state", ("width",)),
    "ee_pose": ("state", _POSE),
    "action": ("action", (*(f"target_{name}" for name in _POSE), "gripper_width")),
    "goal": ("other", ("x", "y")),
}
#: A monitored rollout's per-step scores beside its frames (`robofailring.monitor.episodes`), not a view.
MONITOR_FILE: Final[str] = "monitor.npz"


def read_project_manifest(root: Path) -> dict[str, Any]:
    """The project's dataset manifest, validated enough to name what is wrong."""
    path = Path(root) / PROJECT_MANIFEST
    try:
        text = path.read_bytes()
    except OSError as error:
        raise DataError(f"cannot read dataset manifest {path}: {error}") from error
    manifest = parse_json(text, source=f"dataset manifest {path}")
    if (
        not isinstance(manifest, dict)
        or manifest.get("format") != PROJECT_FORMAT
        or not isinstance(manifest.get("episodes"), list)
    ):
        raise DataError(f"{path} is not a robofailring dataset manifest (format {PROJECT_FORMAT!r})")
    check_frame_rate(manifest.get("fps"), where=str(path))  # checked even where each episode has its own
    return dict(manifest)


def project_trajectories(root: Path, manifest: dict[str, Any]) -> Found:
    found = []
    listed = set()
    for record in manifest["episodes"]:
        try:
            directory = root / record["dir"]
            outcome = None if record["outcome"] is None else Outcome(record["outcome"])  # null: not known
            task = record["task"]
        except (KeyError, ValueError) as error:
            raise DataError(f"{root / PROJECT_MANIFEST}: bad episode record {record!r} ({error})") from error
        if not _within(root, str(record["dir"])):
            raise DataError(
                f"{root / PROJECT_MANIFEST} lists {record['dir']!r}, which is not a folder inside the dataset "
                f"{root}: refused (an episode's `dir` is a path relative to the manifest, without `..`)"
            )
        if not directory.is_dir():
            raise DataError(f"{root / PROJECT_MANIFEST} lists {record['dir']} but {directory} is missing")
        listed.add(Path(record["dir"]).parts[0])
        views, inside = aha_files(directory)
        signals, signals_file = project_signals(
            directory, record, where=f"{root / PROJECT_MANIFEST} episode {record['dir']}"
        )
        monitor_file = MONITOR_FILE if isinstance(record.get("monitor"), dict) else None
        inside = [skipped for skipped in inside if skipped.path.name not in (signals_file, monitor_file)]
        wanted = record.get("views")
        if wanted:
            views = {view: views.get(view, ()) for view in wanted}
        trajectory = Trajectory(
            task=task,
            episode=record.get("episode", record["dir"]),
            views=views,
            symbol=record.get("label"),
            outcome=outcome,
            source=directory,
            fps=check_frame_rate(
                record.get("fps", manifest.get("fps")),
                where=f"{root / PROJECT_MANIFEST} episode {record['dir']}",
            ),
            split=record.get("split"),
            skipped=tuple(inside),
            signals=signals,
        )
        if outcome is Outcome.FAILURE:  # manifests from before onsets have none: unknown
            where = f"{root / PROJECT_MANIFEST} episode {record['dir']}"
            onset = parse_onset_frame(record.get("onset_frame"), length=trajectory.length, where=where)
            trajectory = replace(trajectory, onset_frame=onset)
        found.append(trajectory)
    unlisted = [
        Skipped(p, f"not listed in {PROJECT_MANIFEST}")
        for p in sorted(root.iterdir())
        if p.name not in listed and p.name != PROJECT_MANIFEST and not p.name.startswith(".")
    ]
    return found, unlisted


def _within(root: Path, folder: str) -> bool:
    """A manifest's `dir`: relative, and still inside the dataset once `..` is resolved."""
    if not folder or Path(folder).is_absolute():
        return False
    joined = os.path.normpath(os.path.join(str(root), folder))
    return joined.startswith(os.path.normpath(str(root)).rstrip(os.sep) + os.sep)


def project_signals(
    directory: Path, record: dict[str, Any], *, where: str
) -> tuple[dict[str, Signal], str | None]:
    """An episode's signals as its record describes them (`signals`: the `.npz` file beside its frames,
    each signal's kind and dimension names), and that file's name; none for records from before signals."""
    described = record.get("signals")
    if described is None:
        return {}, None
    try:
        file = str(described["file"])
        signals = {
            str(name): Signal(
                name=str(name),
                kind=SignalKind(spec["kind"]),
                source=NpzSignal(directory / file, str(name)),
                dims=tuple(str(dim) for dim in spec.get("names") or ()),
            )
            for name, spec in described["signals"].items()
        }
    except (KeyError, TypeError, ValueError, AttributeError) as error:
        raise DataError(f"{where}: bad signals record {described!r} ({error!r})") from error
    if Path(file).name != file or file.startswith("."):
        raise DataError(f"{where}: signals file {file!r} is not a file name inside the episode's folder")
    return signals, file


def folder_signals(directory: Path) -> tuple[dict[str, Signal], str | None]:
    """A project episode's `signals.npz` read without the dataset's manifest (the episode folder copied
    elsewhere), described as `generate` writes it, and that file's name; none where the folder has no such
    file, or one holding arrays `generate` does not write (then it is another program's, listed unread)."""
    path = directory / SIGNALS_FILE
    if not path.is_file():
        return {}, None
    try:
        with np.load(path, allow_pickle=False) as stored:
            names = list(stored.files)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile):
        return {}, None  # listed as a file not read, as before
    if not names or any(name not in PROJECT_SIGNALS for name in names):
        return {}, None
    signals = {
        name: Signal(
            name=name,
            kind=SignalKind(PROJECT_SIGNALS[name][0]),
            source=NpzSignal(path, name),
            dims=PROJECT_SIGNALS[name][1],
        )
        for name in names
    }
    return signals, SIGNALS_FILE


@dataclass(frozen=True)
class NpzSignal:
    """One array of an episode's `signals.npz` (read without pickles)."""

    file: Path
    key: str

    def load(self) -> np.ndarray:
        return read_npz(self.file, error=DataError, names=[self.key])[self.key]

    @property
    def reference(self) -> str:
        return f"{self.file}#{self.key}"


def _detect(root: Path) -> bool:
    return (root / PROJECT_MANIFEST).is_file()


def _read(root: Path, *, task: str | None = None) -> Found:
    return project_trajectories(root, read_project_manifest(root))


LAYOUT: Final = register(
    Layout(
        name="project",
        detect=_detect,
        read=_read,
        help="the project's own layout (a manifest.json written by `robofailring generate`)",
        listed=1,
        detect_order=10,  # first: its manifest says what it is (its episode folders are AHA-named too)
        manifest=read_project_manifest,
    )
)
