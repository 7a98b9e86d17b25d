"""Every monitored episode kept for review, as a dataset in the project's own layout (docs/data.md).

`RolloutStore` is that dataset's folder: `manifest.json` and one folder per episode (`<view>_<t>.png` for every
frame judged, `signals.npz` with the robot's signals and the action of each frame, `monitor.npz` with the
monitor's per-step scores, threshold and alarm). An episode is written into a hidden staging folder as it runs
(its frames as they come, so memory does not grow with them) and renamed into place when it ends, then the
manifest is replaced atomically: a process killed at any moment leaves every finished episode readable by
`replay`, `review`, `triage`, `evaluate` and `load_dataset`.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

import numpy as np

from robofailring.atomic import output_lock, write_text_atomic
from robofailring.data.images import write_png
from robofailring.data.layouts.project import (
    MONITOR_FILE,
    PROJECT_FORMAT,
    PROJECT_MANIFEST,
    SIGNALS_FILE,
    read_project_manifest,
)
from robofailring.data.model import Outcome
from robofailring.data.signals import SignalKind
from robofailring.errors import DataError, OutputError
from robofailring.monitor.verdict import Verdict

_log = logging.getLogger("robofailring")
GENERATOR: Final[str] = "robofailring.monitor"
_STAGING: Final[str] = ".staging-"


@dataclass
class EpisodeDraft:
    """One episode being written: its frames on disk already, its signals and scores held until it ends."""

    folder: Path
    name: str
    task: str
    views: list[str] = field(default_factory=list)
    frames: int = 0
    signals: dict[str, list[np.ndarray | None]] = field(default_factory=dict)
    kinds: dict[str, SignalKind] = field(default_factory=dict)
    dims: dict[str, tuple[str, ...]] = field(
        default_factory=dict
    )  # the memory's dimension names, where it has them
    scores: dict[str, list[float]] = field(default_factory=dict)
    thresholds: list[float] = field(default_factory=list)
    alarms: list[bool] = field(default_factory=list)
    first_alarm: int | None = None

    def add(
        self,
        images: dict[str, np.ndarray],
        signals: dict[str, np.ndarray],
        kinds: dict[str, SignalKind],
        verdict: Verdict,
    ) -> None:
        """Frame `self.frames`: its images written now, its signals and the verdict's scores kept."""
        t = self.frames
        if not self.views:
            self.views = list(images)
        for view in self.views:
            write_png(self.folder / f"{view}_{t}.png", images[view])
        for name in signals:
            self.signals.setdefault(name, [None] * t)
            self.kinds.setdefault(name, kinds[name])
        for name, rows in self.signals.items():
            rows.append(signals.get(name))
        for view, score in verdict.scores.items():
            self.scores.setdefault(view, [float("nan")] * t).append(score)
        for scored in self.scores.values():
            if len(scored) == t:  # a view scored before and not now
                scored.append(float("nan"))
        self.thresholds.append(verdict.threshold)
        self.alarms.append(verdict.alarm)
        if verdict.alarm and self.first_alarm is None:
            self.first_alarm = t
        self.frames = t + 1

    def write_arrays(self) -> tuple[dict[str, Any] | None, list[str]]:
        """`signals.npz` and `monitor.npz` into the folder: the manifest's signals record and the notes on
        signals with frames missing or not finite (written as NaN, kept: the loader names them)."""
        notes: list[str] = []
        arrays: dict[str, np.ndarray] = {}
        described: dict[str, dict[str, Any]] = {}
        for name, rows in self.signals.items():
            width = next(len(row) for row in rows if row is not None)
            bad = [
                t
                for t, row in enumerate(rows)
                if row is None or len(row) != width or not np.isfinite(row).all()
            ]
            if bad:
                notes.append(
                    f"signal {name!r}: {len(bad)} frame(s) missing or not finite (the first {bad[0]})"
                )
            arrays[name] = np.stack(
                [row if row is not None and len(row) == width else np.full(width, np.nan) for row in rows]
            ).astype(np.float32)
            names = self.dims.get(name, ())
            described[name] = {
                "kind": self.kinds[name].value,
                "names": list(names) if len(names) == width else [],
            }
        if arrays:
            np.savez(self.folder / SIGNALS_FILE, **arrays)  # type: ignore[arg-type]  # numpy's stub types **kwds as allow_pickle
        np.savez(
            self.folder / MONITOR_FILE,
            threshold=np.asarray(self.thresholds, np.float32),
            alarm=np.asarray(self.alarms, bool),
            **{f"score/{view}": np.asarray(rows, np.float32) for view, rows in self.scores.items()},  # type: ignore[arg-type]
        )
        return ({"file": SIGNALS_FILE, "signals": described} if arrays else None), notes


@dataclass(frozen=True)
class EpisodeEnd:
    """How a monitored episode ended: the env's own outcome where it gave one, and why it ended."""

    outcome: Outcome | None  # the env's `is_success`/`success`; None: it gave none, or the monitor cut it
    reason: str  # terminated, truncated, alarm (on_alarm="truncate"), reset, closed
    stopped: str | None = None  # the monitor's reason for cutting it at an alarm


class RolloutStore:
    """The saved rollouts: a project-layout dataset at `root`, appended to one episode at a time.

    `root` must be absent, empty or rollouts saved before (appended to); anything else is refused. The
    folder is locked while the store is open (a second monitor writing it gets `OutputBusyError`).
    """

    def __init__(self, root: Path, *, fps: float | None = None) -> None:
        self.root = Path(root)
        self.fps = fps
        self._lock = contextlib.ExitStack()
        self._lock.enter_context(output_lock(self.root))
        try:
            self.records = self._existing()
            self._next = len(
                self.records
            )  # the next episode's number (drafts of a vector env's sub-envs overlap)
            self.root.mkdir(parents=True, exist_ok=True)
            for leftover in sorted(self.root.glob(f"{_STAGING}*")):
                _log.warning("warning: %s is an episode a killed process never finished: removed", leftover)
                shutil.rmtree(leftover, ignore_errors=True)
        except BaseException:
            self._lock.close()
            raise

    def _existing(self) -> list[dict[str, Any]]:
        if not self.root.exists():
            return []
        if not self.root.is_dir():
            raise OutputError(f"cannot save rollouts in {self.root}: it is a file")
        if not (self.root / PROJECT_MANIFEST).is_file():
            names = sorted(p.name for p in self.root.iterdir() if not p.name.startswith("."))
            if names:
                raise OutputError(
                    f"cannot save rollouts in {self.root}: it holds {', '.join(names[:3])}, and is not rollouts "
                    "a monitor saved; choose a new or empty folder"
                )
            return []
        manifest = read_project_manifest(self.root)
        if manifest.get("generator") != GENERATOR:
            raise OutputError(
                f"cannot save rollouts in {self.root}: it is a dataset written by "
                f"{manifest.get('generator', 'someone else')}, not rollouts; choose a new or empty folder"
            )
        return list(manifest["episodes"])

    def draft(self, task: str) -> EpisodeDraft:
        """A new episode's staging folder (hidden: no reader sees it until it is kept)."""
        name = f"episode_{self._next:05d}"
        while (self.root / name).exists():
            name = f"{name}_"
        self._next += 1
        folder = self.root / f"{_STAGING}{name}"
        shutil.rmtree(folder, ignore_errors=True)
        folder.mkdir()
        return EpisodeDraft(folder=folder, name=name, task=task)

    def keep(self, draft: EpisodeDraft, end: EpisodeEnd, *, rule: str) -> dict[str, Any] | None:
        """Move a finished episode into place and list it in the manifest; None for one with no frame."""
        if not draft.frames:
            shutil.rmtree(draft.folder, ignore_errors=True)
            return None
        signals, notes = draft.write_arrays()
        os.replace(draft.folder, self.root / draft.name)
        record: dict[str, Any] = {
            "dir": draft.name,
            "episode": draft.name,
            "task": draft.task,
            "label": None,
            "outcome": end.outcome.value if end.outcome is not None else None,
            "views": draft.views,
            "frames": draft.frames,
            "monitor": {
                "file": MONITOR_FILE,
                "rule": rule,
                "alarm_frame": draft.first_alarm,
                "ended": end.reason,
                "stopped": end.stopped,
                "notes": notes,
            },
        }
        if self.fps is not None:
            record["fps"] = self.fps
        if signals is not None:
            record["signals"] = signals
        self.records.append(record)
        self._write_manifest()
        return record

    def _write_manifest(self) -> None:
        manifest = {
            "format": PROJECT_FORMAT,
            "format_version": 1,
            "generator": GENERATOR,
            "views": sorted({view for record in self.records for view in record["views"]}),
            "tasks": sorted({record["task"] for record in self.records}),
            "episodes": self.records,
        }
        if self.fps is not None:
            manifest["fps"] = self.fps
        write_text_atomic(self.root / PROJECT_MANIFEST, json.dumps(manifest, indent=1) + "\n")

    def discard(self, draft: EpisodeDraft) -> None:
        """Remove an episode that is not kept (its staging folder)."""
        shutil.rmtree(draft.folder, ignore_errors=True)

    def close(self) -> None:
        """Release the folder's lock."""
        self._lock.close()


def read_rollouts(root: Path) -> list[dict[str, Any]]:
    """The episode records of rollouts a monitor saved (its manifest), for the summary."""
    manifest = read_project_manifest(Path(root))
    if manifest.get("generator") != GENERATOR:
        raise DataError(f"{Path(root) / PROJECT_MANIFEST} lists no rollouts a monitor saved")
    return list(manifest["episodes"])
