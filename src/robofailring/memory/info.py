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


def selection_text(described: dict[str, Any]) -> list[str]:
    """memory-info's lines on one task's choice of signal elements (`--signals auto`): which it chose from the
    task's training runs, with what weight and why, or why every element was kept."""
    selection = described.get("selection")
    if selection is None:
        return [f"      {described.get('selection_skipped') or 'every element of its vectors kept'}"]
    chosen = ", ".join(
        f"{c['group']} (AUC alone {c['auc_alone']:.2f}, with those before {c['auc_with']:.2f})"
        for c in selection["chosen"]
    )
    return [
        f"      chosen (weight 1): {chosen}",
        f"      the moment (frame number) weighted {selection['phase_weight']:g}; {selection['why']}",
    ]


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
            "signals": self._signals(),
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

    def _signals(self) -> dict[str, Any] | None:
        """The signal memory: how its signals were chosen, and per task the signals and dimensions it judges
        (state, then action), its derived features and its entries (None: the cameras alone)."""
        signals = self.memory.signals
        if signals is None:
            return None
        section = self.memory.manifest.signals
        stored = section.tasks if section is not None else {}  # its choice, as the manifest keeps it
        tasks = {}
        for task, held in sorted(signals.by_task.items()):
            vectors = next(iter(held.vectors.values()), None)
            tasks[task] = {
                "state": {name: list(dims) for name, dims in held.layout.state},
                "action": {name: list(dims) for name, dims in held.layout.action},
                "dimensions": sum(held.layout.widths),
                "derived": held.derivation.width if held.derivation is not None else 0,
                "vector_dim": int(vectors.shape[1]) if vectors is not None else 0,
                **{f"{kind}_entries": len(values) for kind, values in held.vectors.items()},
                **(
                    {"selection": stored[task].selection} if task in stored and stored[task].selection else {}
                ),
                **(
                    {"selection_skipped": stored[task].selection_skipped}
                    if task in stored and stored[task].selection_skipped is not None
                    else {}
                ),
            }
        return {
            "choice": signals.choice,
            "features": str(signals.features),
            "start_weight": signals.start_weight,
            "tasks": tasks,
        }

    def _signals_lines(self, found: dict[str, Any] | None) -> list[str]:
        if found is None:
            return [
                "  signals     none: the cameras alone (built with --signals none, or data without signals)"
            ]
        lines = [
            f"  signals     the robot's own, chosen {found['choice']}; derived features {found['features']}, "
            f"start weight {found['start_weight']:g}"
        ]
        for task, held in found["tasks"].items():
            named = [
                f"{kind} " + ", ".join(f"{name} ({len(dims)})" for name, dims in held[kind].items())
                for kind in ("state", "action")
                if held[kind]
            ]
            lines.append(
                f"    {task}  {'; '.join(named)}: {held['dimensions']} dimensions (+{held['derived']} derived), "
                f"{held.get('failure_entries', 0)} failure and {held.get('success_entries', 0)} success "
                f"entries of {held['vector_dim']}-d"
            )
            if found["choice"] == "auto":
                lines += selection_text(held)
        return lines

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
        lines += self._signals_lines(info["signals"])
        refs = info["references"]
        lines.append(f"  images      {refs['found']} of {refs['total']} reference images found")
        if refs["first_missing"]:
            lines.append(f"              first missing: {refs['first_missing']}")
        if info["success_only_tasks"]:
            lines.append(
                f"  no failures {', '.join(info['success_only_tasks'])}: success runs only, judged by the novelty rule"
            )
        lines.append("  per task and view:")
        width = max((len(task) for task in info["tasks"]), default=4)
        for task, views in info["tasks"].items():
            cells = ", ".join(f"{view} {count}" for view, count in views.items())
            lines.append(f"    {task:<{width}}  {cells}")
        return "\n".join(lines)
