"""The nearest success frame sent as column batches holds the rows `log_nearest_success` logs frame by frame."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import rerun as rr
from rrd import batches

from rfr_viz.panels.contrast import _send_nearest_success, log_nearest_success
from rfr_viz.panels.images import ReferenceJpegs
from rfr_viz.panels.scores import set_frame_time
from rfr_viz.paths import REPLAY
from robofailring.data.images import encode_jpeg
from robofailring.memory.image_roots import ImageRoots
from robofailring.memory.success import SuccessMatch, SuccessRun

VIEW = "agentview"
FPS = 20.0  # frame 41 is 2.05 s: truncated to the nanosecond it would be 2049999999 ns


def content(path: Path) -> list[tuple[Any, ...]]:
    """(entity, frame, time in ns, column, value) of every temporal row, whatever the chunks."""
    found = []
    for entity in (REPLAY.nearest_success(VIEW), REPLAY.nearest_success_info(VIEW)):
        for batch in batches(path, entity):
            if "frame" not in batch.schema.names:
                continue
            frames = batch.column("frame").to_pylist()
            times = batch.column("time").cast(pa.int64()).to_pylist()
            for name in batch.schema.names:
                if ":" in name:  # the components: Clear:is_recursive, EncodedImage:blob, …
                    for i, value in enumerate(batch.column(name).to_pylist()):
                        if value is not None:
                            found.append((entity, frames[i], times[i], name, repr(value)))
    return sorted(found)


def test_column_batches_hold_the_rows_logged_frame_by_frame(tmp_path: Path) -> None:
    picture = tmp_path / "success_0003.jpg"
    picture.write_bytes(encode_jpeg(np.full((8, 8, 3), 128, np.uint8), quality=90))
    run = SuccessRun(
        task="Lift", episode="demo_1", view=VIEW, frames=(str(picture), str(tmp_path / "gone.jpg"))
    )
    found = SuccessMatch(index=0, similarity=0.9, run=run, row=0)
    missing = SuccessMatch(index=1, similarity=0.7, run=run, row=1)
    # no match, a picture that changed, the same one again, a missing picture, no match again
    matches: list[tuple[int, SuccessMatch | None]] = [
        (0, None),
        (41, found),
        (42, found),
        (82, missing),
        (83, None),
    ]
    changed = {41, 82}
    paths = {name: tmp_path / f"{name}.rrd" for name in ("rows", "columns")}

    rec = rr.RecordingStream("test", recording_id="rows")
    rec.save(paths["rows"])
    images = ReferenceJpegs(ImageRoots.of(tmp_path))
    for t, match in matches:
        set_frame_time(rec, t, FPS)
        log_nearest_success(rec, REPLAY, VIEW, match, t=t, images=images, image=t in changed)
    rec.disconnect()

    rec = rr.RecordingStream("test", recording_id="columns")
    rec.save(paths["columns"])
    _send_nearest_success(
        rec, REPLAY, VIEW, matches, changed=changed, images=ReferenceJpegs(ImageRoots.of(tmp_path)), fps=FPS
    )
    rec.disconnect()

    logged = content(paths["rows"])
    assert {row[3] for row in logged} >= {"Clear:is_recursive", "EncodedImage:blob", "TextDocument:text"}
    assert any("image not found" in row[4] for row in logged)
    assert content(paths["columns"]) == logged
