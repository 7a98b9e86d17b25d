"""Contact sheet of a generated dataset: the last frame per failure mode (rows) and view (columns)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from robofailring.atomic import atomic_path
from robofailring.data.grounding import failure_type
from robofailring.data.images import read_image
from robofailring.data.layouts import read_project_manifest
from robofailring.errors import DataError
from robofailring.sim.perturb import FAILURE_FAMILIES, SUCCESS

_MARGIN = 112
_HEADER = 34
_FONT = cv2.FONT_HERSHEY_SIMPLEX


def _text(
    image: np.ndarray, text: str, origin: tuple[int, int], *, scale: float = 0.4, boxed: bool = False
) -> None:
    if not text:
        return
    if boxed:
        (w, h), base = cv2.getTextSize(text, _FONT, scale, 1)
        x, y = origin
        cv2.rectangle(image, (x - 2, y - h - 2), (x + w + 2, y + base), (30, 30, 30), -1)
        cv2.putText(image, text, origin, _FONT, scale, (255, 255, 255), 1, cv2.LINE_AA)
    else:
        cv2.putText(image, text, origin, _FONT, scale, (20, 20, 20), 1, cv2.LINE_AA)


def contact_sheet(
    dataset: Path,
    out_png: Path,
    *,
    tasks: Sequence[str] | None = None,
    tile: int = 128,
    frame: int = -1,
) -> Path:
    """Write a PNG grid: one row per failure family plus success, one column per (task, view).

    Each row shows the first episode of the task whose outcome matches the row (a failure of that
    family, or a success without perturbation), at `frame` (default: the last), labelled with its
    symbol. Cells with no such episode stay grey.
    """
    dataset = Path(dataset)
    manifest = read_project_manifest(dataset)
    views: list[str] = list(manifest.get("views", ["front", "overhead", "wrist"]))
    chosen = list(tasks) if tasks is not None else list(manifest.get("tasks", []))
    if not chosen:
        raise DataError(f"{dataset}: no tasks to show")
    rows = [*FAILURE_FAMILIES, SUCCESS]
    width = _MARGIN + tile * len(views) * len(chosen)
    sheet = np.full((_HEADER + tile * len(rows), width, 3), 235, dtype=np.uint8)
    for t, task in enumerate(chosen):
        for v, view in enumerate(views):
            x = _MARGIN + (t * len(views) + v) * tile
            _text(sheet, task if v == 0 else "", (x + 4, 14))
            _text(sheet, view, (x + 4, 29))
    for r, family in enumerate(rows):
        y = _HEADER + r * tile
        _text(sheet, family, (6, y + tile // 2), scale=0.42)
        for t, task in enumerate(chosen):
            record = _pick(manifest["episodes"], task, family)
            if record is None:
                continue
            for v, view in enumerate(views):
                x = _MARGIN + (t * len(views) + v) * tile
                frames = int(record["frames"])
                index = frame if frame >= 0 else frames + frame
                image = read_image(dataset / record["dir"] / f"{view}_{index}.png")
                sheet[y : y + tile, x : x + tile] = cv2.resize(
                    image, (tile, tile), interpolation=cv2.INTER_AREA
                )
                if v == 0:
                    label = str(record["label"] or SUCCESS)
                    text_width = cv2.getTextSize(label, _FONT, 0.35, 1)[0][0]
                    scale = 0.35 * min(1.0, (tile - 10) / text_width)
                    _text(sheet, label, (x + 4, y + 13), scale=scale, boxed=True)
        cv2.line(sheet, (0, y), (width, y), (180, 180, 180), 1)
    out_png = Path(out_png)
    out_png.parent.mkdir(parents=True, exist_ok=True)
    ok, encoded = cv2.imencode(".png", sheet[:, :, ::-1], [cv2.IMWRITE_PNG_COMPRESSION, 9])
    if not ok:
        raise DataError(f"cannot encode contact sheet {out_png}")
    with atomic_path(out_png) as tmp:
        tmp.write_bytes(encoded.tobytes())
        tmp.chmod(0o644)
    return out_png


def _pick(records: list[dict[str, Any]], task: str, family: str) -> dict[str, Any] | None:
    for record in records:
        if record["task"] != task:
            continue
        label = record.get("label")
        if family == SUCCESS and label is None and record.get("perturbation") is None:
            return record
        if isinstance(label, str) and failure_type(label) == family:
            return record
    return None
