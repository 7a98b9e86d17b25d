"""Failure report R (eq. 8) and the VLM prompt of Appendix B, as JSON, Markdown and chat messages."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from robofailring.errors import DataError
from robofailring.memory.entry import moment_text
from robofailring.memory.failure import Neighbor
from robofailring.memory.image_roots import ImageRoots
from robofailring.memory.references import (
    absolute_reference,
    check_references,
    relocate,
)
from robofailring.memory.signals.modality import SIGNALS_VIEW

if TYPE_CHECKING:
    from robofailring.data.model import Trajectory
    from robofailring.detection.detector import DetectionTrace
    from robofailring.detection.signal_scores import SignalScores

SYSTEM_PROMPT = (
    "You are an expert robotic failure analyst. Use the provided Failure Report and Reference Images "
    "to diagnose the Current Situation."
)
INTRO = (
    "Robot stopped now because the current scene is similar to the failure memory. I have retrieved a "
    "similar historical failure case from memory. Details of Failure Report as follows:"
)
TASKS = (
    "Based on this report, please reasoning why it failed and how should it be repaired? You tasks are:\n"
    "1. Compare the Current Observation with the Reference End Frame.\n"
    "2. Confirm if the failure mode described in the report matches the visual evidence.\n"
    "3. Provide a reasoning for the failure cause.\n"
    "4. Suggest a concrete repair action."
)
ASSISTANT_PRIMER = "Got it. Here's the analysis of the current situation:"
NO_FAILURES = (
    "No failure of this task in the memory (success runs only): the run is far from every success run, "
    "but there is no past failure to compare it with."
)
SIGNALS_ALONE = (
    "The robot's signals fired (their nearest runs are above); no camera view's failure neighbours are shown "
    "(no camera was judged beside them, or the memory has no failure of this task)."
)


@dataclass(frozen=True)
class ReportItem:
    """One tuple of eq. 8: (τ, G(y_sym), ω, I_start, I_end) plus the similarity and symbol; in a dense
    memory `end_image` is the run's frame `frame` of `length` (None: its last, the paper's)."""

    task: str
    symbol: str
    description: str
    view: str
    similarity: float
    start_image: str
    end_image: str
    frame: int | None = None
    length: int | None = None

    @property
    def moment(self) -> str:
        """Which moment of the past failure run `end_image` is (`memory.entry.moment_text`)."""
        return moment_text(self.frame, self.length)

    def to_dict(self) -> dict[str, Any]:
        """The item as a report's JSON holds it (`frame` and `length` only for a dense memory's entry)."""
        stored = {**self.__dict__, "similarity": round(self.similarity, 6)}
        return {
            key: value for key, value in stored.items() if key not in ("frame", "length") or value is not None
        }

    @classmethod
    def from_neighbor(cls, neighbor: Neighbor) -> ReportItem:
        entry = neighbor.entry
        return cls(
            task=entry.task,
            symbol=entry.symbol,
            description=entry.description,
            view=entry.view,
            similarity=neighbor.similarity,
            start_image=entry.start,
            end_image=entry.end,
            frame=entry.frame,
            length=entry.length,
        )


@dataclass(frozen=True)
class FailureReport:
    """The report produced at the detection instant for the K neighbours of the firing view."""

    current_task: str
    view: str
    t_det: int
    similarity: float
    items: tuple[ReportItem, ...]
    current_image: str | None = None
    # the robot's own signals at t_det: their S⁻ and S⁺, nearest runs and the dimensions that deviated
    # most from the nearest normal frame (None: the memory or the run has no signals)
    signals: str | None = None
    # the folders its images may be read from, named where it was made (the memory's `image_roots`, the
    # run's own folder) or opened (`explain`: --data-root): an image outside
    # them is never sent (`images_outside`); a report file's own `roots` are written but never trusted
    roots: tuple[str, ...] = ()

    @classmethod
    def from_neighbors(
        cls,
        *,
        task: str,
        view: str,
        t_det: int,
        neighbors: Sequence[Neighbor],
        current_image: str | None = None,
        similarity: float | None = None,
        signals: str | None = None,
        roots: Sequence[str] = (),
    ) -> FailureReport:
        """The report of `neighbors` (K entries of one camera view); `similarity` the firing view's S⁻
        when that is not the top neighbour's (the signals fired)."""
        items = tuple(ReportItem.from_neighbor(n) for n in neighbors)
        if similarity is None:
            similarity = items[0].similarity if items else float("nan")
        return cls(task, view, t_det, similarity, items, current_image, signals, tuple(roots))

    @classmethod
    def from_dict(
        cls, data: Mapping[str, Any], *, source: str = "report", roots: Sequence[str | Path] = ()
    ) -> FailureReport:
        """The inverse of `to_dict` (a `detect --json` report, a recording's `report` property), its images
        read only from under `roots` (the folders named where it is opened; the file's own are ignored)."""
        try:
            items = tuple(
                ReportItem(
                    task=str(item["task"]),
                    symbol=str(item["symbol"]),
                    description=str(item["description"]),
                    view=str(item["view"]),
                    similarity=float(item["similarity"]),
                    start_image=str(item["start_image"]),
                    end_image=str(item["end_image"]),
                    frame=_whole_or_none(item.get("frame")),
                    length=_whole_or_none(item.get("length")),
                )
                for item in data["neighbors"]
            )
            current, signals = data.get("current_image"), data.get("signals")
            return cls(
                current_task=str(data["current_task"]),
                view=str(data["view"]),
                t_det=int(data["t_det"]),
                similarity=float(data["similarity"]),
                items=items,
                current_image=None if current is None else str(current),
                signals=None if signals is None else str(signals),
                roots=tuple(map(str, ImageRoots.of(*roots).folders)),
            )
        except (KeyError, TypeError, ValueError) as error:
            raise DataError(f"{source} is not a failure report (missing or bad field: {error})") from error

    def to_dict(self) -> dict[str, Any]:
        return (
            {
                "current_task": self.current_task,
                "view": self.view,
                "t_det": self.t_det,
                "similarity": round(self.similarity, 6),
                "current_image": self.current_image,
                "neighbors": [item.to_dict() for item in self.items],
            }
            | ({"signals": self.signals} if self.signals is not None else {})
            | {"roots": list(self.roots)}
        )

    def prompt_images(self) -> list[str]:
        """The images the VLM prompt shows: the top neighbour's start and end, and the current frame."""
        if not self.items:
            return []
        return [
            self.items[0].start_image,
            self.items[0].end_image,
            *([self.current_image] if self.current_image else []),
        ]

    def missing_images(self) -> list[str]:
        """The prompt's images that are not on disk."""
        return list(check_references(absolute_reference(image) for image in self.prompt_images()).missing)

    def relocated(self, data_root: Path) -> FailureReport:
        """The same report with its images found again under `data_root` (the dataset moved)."""
        items = tuple(
            replace(
                item,
                start_image=relocate(item.start_image, data_root),
                end_image=relocate(item.end_image, data_root),
            )
            for item in self.items
        )
        current = relocate(self.current_image, data_root) if self.current_image else self.current_image
        return replace(
            self, items=items, current_image=current, roots=tuple(map(str, ImageRoots.of(data_root).folders))
        )

    def images_outside(self) -> list[str]:
        """The prompt's images whose files (links followed) lie outside the report's roots: never read nor
        sent (an edited report must not upload another file of yours)."""
        return ImageRoots.of(*self.roots).outside(self.prompt_images())

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2)

    def vlm_messages(self) -> list[dict[str, Any]]:
        """Appendix B as chat messages, built around the top neighbour."""
        if not self.items:
            return []
        top = self.items[0]
        report = {
            "current_task": self.current_task,
            "failure": top.description,
            "view": top.view,
            "similarity_score": f"{top.similarity:.2f}",
        } | ({"robot_signals": self.signals} if self.signals is not None else {})
        messages: list[dict[str, Any]] = [
            {"role": "system", "content": SYSTEM_PROMPT},
            {"role": "user", "content": f"{INTRO}\n{json.dumps(report, indent=2)}"},
            {
                "role": "user",
                "content": [
                    {
                        "type": "text",
                        "text": "Below are the reference images from this historical failure memory:",
                    },
                    {"type": "text", "text": "Reference Start Frame (Task Context):"},
                    {"type": "image", "path": absolute_reference(top.start_image)},
                    {"type": "text", "text": _reference_label(top)},
                    {"type": "image", "path": absolute_reference(top.end_image)},
                ],
            },
        ]
        current: list[dict[str, Any]] = [
            {"type": "text", "text": "Now, look at the current robot observation:"},
            {"type": "text", "text": "Current Frame:"},
        ]
        if self.current_image:
            current.append({"type": "image", "path": absolute_reference(self.current_image)})
        messages.append({"role": "user", "content": current})
        messages.append({"role": "user", "content": TASKS})
        messages.append({"role": "assistant", "content": ASSISTANT_PRIMER})
        return messages

    def to_markdown(self, *, include_prompt: bool = True) -> str:
        lines = [
            f"# Failure report — {self.current_task}",
            "",
            f"Detected at frame **{self.t_det}** in view **{self.view}** with S_t = **{self.similarity:.3f}**.",
            *(["", f"Robot signals: {self.signals}"] if self.signals is not None else []),
            "",
            "| rank | task | view | similarity | symbol | grounded failure | matched moment of that run |",
            "|---:|---|---|---:|---|---|---|",
        ]
        for rank, item in enumerate(self.items):
            lines.append(
                f"| {rank} | {item.task} | {item.view} | {item.similarity:.3f} | `{item.symbol}` | {item.description} | "
                f"{item.moment} |"
            )
        if not self.items:
            lines += [
                "",
                SIGNALS_ALONE if self.view == SIGNALS_VIEW and self.signals is not None else NO_FAILURES,
            ]
        missing = self.missing_images()
        if missing:
            lines += ["", *(f"**image not found:** `{reference}`  " for reference in missing)]
        if include_prompt and self.items:
            lines += ["", "## VLM prompt (Appendix B)", ""]
            for message in self.vlm_messages():
                content = message["content"]
                if isinstance(content, list):
                    content = "\n".join(
                        part.get("text") or f"![image]({part.get('path')})" for part in content
                    )
                lines += [f"**{message['role']}**:", "", "```text", str(content), "```", ""]
        return "\n".join(lines)


def _reference_label(item: ReportItem) -> str:
    """Appendix B's label of the reference's second image; a dense memory's moment before the run's end says which."""
    if item.frame is None or item.length is None or item.frame == item.length - 1:
        return "Reference End Frame (Failure State):"
    return f"Reference Frame at the Matched Moment, {item.moment}:"


def _whole_or_none(value: Any) -> int | None:
    """A report's optional frame number (absent in reports of the paper's memory)."""
    return None if value is None else int(value)


def report_for(trace: DetectionTrace, trajectory: Trajectory | None = None) -> FailureReport | None:
    """The report at t_det for the firing view's K neighbours (None without a detection); when the robot's
    signals fired, the neighbours of the camera view scoring highest then, and the signals' sentence.

    With the trajectory, the current frame (that camera at t_det) is referenced for the VLM.
    """
    t_det, view = trace.t_det, trace.detected_view
    if t_det is None or view is None:
        return None
    camera = trace.camera_at(view, t_det)
    current = None
    if (
        camera is not None
        and trajectory is not None
        and camera in trajectory.views
        and t_det < len(trajectory.views[camera])
    ):
        current = trajectory.views[camera][t_det].reference
    return FailureReport.from_neighbors(
        task=trace.task,
        view=view,
        t_det=t_det,
        neighbors=trace.neighbors(camera, t_det) if camera is not None else [],
        current_image=current,
        similarity=None if camera == view else float(trace.failure_similarity(view)[t_det]),
        signals=signals_sentence(trace.signals, t_det),
        roots=_roots(trace, trajectory),
    )


def _roots(trace: DetectionTrace, trajectory: Trajectory | None) -> list[str]:
    """Where a report's images may come from: the folders named for the memory's images (its neighbours;
    `FailureMemory.image_roots`) and the run's own folder or file's folder (its current frame)."""
    source = trajectory.source if trajectory is not None else trace.source
    folder = Path(source).resolve() if source is not None else None
    run = (folder if folder.is_dir() else folder.parent) if folder is not None else None
    return list(map(str, trace.memory.image_roots.joined(ImageRoots.of(run)).folders))


def signals_sentence(signals: SignalScores | None, t: int) -> str | None:
    """What the robot's signals say at frame `t` of their scores (a trace's `signals`, a live session's
    `signal_scores` at row 0): their S⁻ (nearest failure run and frame) and S⁺ (nearest normal frame), and
    the dimensions furthest from that normal frame, in σ of the success runs."""
    if signals is None or not np.isfinite(signals.similarity[t]):
        return None
    failure, normal = signals.nearest_failure(t), signals.nearest_success(t)
    parts = [f"S⁻ = {float(signals.similarity[t]):.3f}"]
    if failure is not None:
        parts[0] += f" (nearest failure: {failure[0]}, `{failure[1]}`, frame {failure[2]})"
    if normal is not None:
        parts.append(
            f"S⁺ = {float(signals.success_similarity[t]):.3f} (nearest normal: {normal[0]}, frame {normal[1]})"
        )
        deviated = signals.deviation_text(t)
        if deviated:
            parts.append(f"furthest from normal: {deviated}")
    return "; ".join(parts)


class VLMClient(Protocol):
    """A vision-language model answering chat messages (`robofailring.explain.vlm.ChatCompletionsClient`)."""

    def complete(self, messages: list[dict[str, Any]]) -> str: ...
