"""What a saved memory holds: encoder, counts per task and view, thresholds, data root, references."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from robofailring.memory.entry import DENSE
from robofailring.memory.failure import FailureMemory
from robofailring.memory.pairs import CHANGE
from robofailring.memory.references import ReferenceCheck


def failure_memory_text(memory: FailureMemory) -> str:
    """Which failure memory `memory` holds, with its counts: "dense, 1,904 entries from 112 failure views
    (…)" or "end (the paper's), 112 entries from 112 failure views (…)"."""
    manifest = memory.manifest
    views = len({(entry.task, entry.episode, entry.view) for entry in memory.entries})
    counts = f"{len(memory):,} entries from {views:,} failure views"
    pairing = (
        "paired as the change since the first frame, norm([½ z_0 ‖ z_t − z_0])"
        if manifest.pairing_mode == CHANGE
        else "paired as the paper's norm([z_0 ‖ z_t])"
    )
    if manifest.failure_mode == DENSE:
        step = f"{manifest.failure_step:g}" if manifest.failure_step is not None else "?"
        return (
            f"dense, {counts} (each view's frames from the failure's onset on, from frame 1 where it is "
            f"not known, thinned at step {step}; {pairing})"
        )
    return f"end (the paper's), {counts} (each view's first and last frame; {pairing})"


def signals_text(section: dict[str, Any] | None) -> list[str]:
    """memory-info's lines on the signal memory: per task the dimensions it uses, and with `--signals auto` which
    it chose from the task's training runs, with what weight and why."""
    if not section:
        return ["  signals     none (the cameras alone)"]
    lines = [
        f"  signals     --signals {section.get('choice')}, derived features {section.get('features')}, start "
        f"weight {section.get('start_weight')}"
    ]
    for task, described in sorted(section.get("tasks", {}).items()):
        layout = described.get("layout", {})
        dims = sum(len(d) for kind in ("state", "action") for _, d in layout.get(kind, []))
        lines.append(
            f"    {task}: {dims} dimensions of {', '.join(n for kind in ('state', 'action') for n, _ in layout.get(kind, []))}"
        )
        selection = described.get("selection")
        if selection is None:
            lines.append(f"      {described.get('selection_skipped') or 'every element of its vectors kept'}")
            continue
        chosen = ", ".join(
            f"{c['group']} (AUC alone {c['auc_alone']:.2f}, with those before {c['auc_with']:.2f})"
            for c in selection["chosen"]
        )
        lines.append(f"      chosen (weight 1): {chosen}")
        lines.append(
            f"      the moment (frame number) weighted {selection['phase_weight']:g}; {selection['why']}"
        )
    return lines


@dataclass(frozen=True)
class MemoryInfo:
    """A summary of one memory folder, for people (`to_text`) and scripts (`to_dict`)."""

    directory: Path
    memory: FailureMemory
    recorded_root: str | None  # the data root the manifest records (None: an older memory)
    references: ReferenceCheck

    @classmethod
    def read(cls, directory: Path, *, data_root: Path | None = None) -> MemoryInfo:
        memory = FailureMemory.load(directory, data_root=data_root)
        return cls(
            directory=Path(directory),
            memory=memory,
            recorded_root=memory.manifest.data_root,
            references=memory.check_references(),
        )

    def counts(self) -> dict[str, dict[str, int]]:
        """Entries per task and view."""
        table: dict[str, Counter[str]] = {}
        for entry in self.memory.entries:
            table.setdefault(entry.task, Counter())[entry.view] += 1
        return {task: dict(sorted(views.items())) for task, views in sorted(table.items())}

    def to_dict(self) -> dict[str, Any]:
        manifest = self.memory.manifest
        return {
            "memory": str(self.directory),
            "format_version": manifest.format_version,
            "encoder": self.memory.encoder,
            "encoder_spec": manifest.encoder_spec,
            "dim": self.memory.dim,
            "entries": len(self.memory),
            "failure_frames": manifest.failure_mode,
            "pairing": manifest.pairing_mode,
            "failure_step": manifest.failure_step,
            "tasks": self.counts(),
            "symbols": dict(sorted(Counter(e.symbol for e in self.memory.entries).items())),
            "calibration": manifest.calibration.to_dict() if manifest.calibration else None,
            "calibrated_thresholds": self._calibrated(),  # by rule name, for the memory's encoder
            "success_only_tasks": [t for t in self.memory.tasks if not self.memory.has_failures(t)],
            "successes": self._successes(),
            "source": manifest.source,
            "layout": manifest.layout,
            "views_read": manifest.data_views,
            "data_root": self.recorded_root,
            "data_root_used": str(self.memory.data_root) if self.memory.data_root else None,
            "references": {
                "total": self.references.total,
                "found": self.references.found,
                "missing": len(self.references.missing),
                "first_missing": self.references.missing[0] if self.references.missing else None,
            },
            "created": manifest.created,
            "signals": manifest.signals,  # the signal memory's section: choice, per task its layout and selection
        }

    def _calibrated(self) -> dict[str, float]:
        calibration = self.memory.manifest.calibration
        names = calibration.rules if calibration is not None else {}
        found = {name: self.memory.calibrated_threshold(name) for name in names}
        return {name: value for name, value in found.items() if value is not None}

    def _successes(self) -> dict[str, Any] | None:
        successes = self.memory.successes
        if successes is None:
            return None
        return {
            "frames": len(successes),
            "offered": successes.offered,
            "runs": successes.success_runs,
            "thinning": successes.thinning,
            "index": {task: index.spec.to_dict() for task, index in sorted(successes.index.by_task.items())},
        }

    def to_text(self) -> str:
        info = self.to_dict()
        calibrated = ", ".join(f"{name} {value:.6f}" for name, value in info["calibrated_thresholds"].items())
        lines = [
            f"memory {self.directory} (format {info['format_version']}, created {info['created'] or '?'})",
            f"  encoder     {info['encoder']}"
            + (f"  (spec {info['encoder_spec']})" if info["encoder_spec"] else ""),
            f"  entries     {info['entries']} × {info['dim']}-d over {len(info['tasks'])} task(s)",
            f"  failures    {failure_memory_text(self.memory)}",
            "  thresholds  "
            + (f"calibrated: {calibrated}" if calibrated else "not calibrated (each rule's default)"),
            f"  data root   {info['data_root'] or '(not recorded: references are as given at build time)'}",
        ]
        if info["layout"]:
            views = ", ".join(info["views_read"] or []) or "(not recorded)"
            lines.append(f"  read as     {info['layout']} layout, views {views}")
        if info["data_root_used"] and info["data_root_used"] != info["data_root"]:
            lines.append(f"  looked in   {info['data_root_used']} (--data-root)")
        found = info["successes"]
        if found is None:
            lines.append(
                "  successes   none: the paper's rule only (built with --no-successes, or before success contrast)"
            )
        else:
            kinds = sorted({spec["kind"] for spec in found["index"].values()})
            lines.append(
                f"  successes   {found['frames']} frames kept of {found['offered']} offered, {found['runs']} success "
                f"views; index {', '.join(kinds)}"
            )
        refs = info["references"]
        lines.append(f"  images      {refs['found']} of {refs['total']} reference images found")
        if refs["first_missing"]:
            lines.append(f"              first missing: {refs['first_missing']}")
        if info["success_only_tasks"]:
            lines.append(
                f"  no failures {', '.join(info['success_only_tasks'])}: success runs only, judged by the novelty rule"
            )
        lines += signals_text(info["signals"])
        lines.append("  per task and view:")
        width = max((len(task) for task in info["tasks"]), default=4)
        for task, views in info["tasks"].items():
            cells = ", ".join(f"{view} {count}" for view, count in views.items())
            lines.append(f"    {task:<{width}}  {cells}")
        return "\n".join(lines)
