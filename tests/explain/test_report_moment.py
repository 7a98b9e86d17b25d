"""The failure report names the moment of the past failure that matched: a dense memory's frame beside its
image, the end of the run for the paper's memory; reports saved before frames existed read back as ends."""

from __future__ import annotations

from pathlib import Path

import pytest
from synthetic import repeated_failure_memory

from robofailring import CachedEncoder, FailureDetector
from robofailring.explain.report import FailureReport, report_for

LENGTH = 8
ONSET = 2


def _report(root: Path, encoder: CachedEncoder, failure_frames: str) -> FailureReport:
    """The report of a new grasp failure whose frames are those of the memory's episode 0, fired at the
    first frame that pairs exactly like one of the memory's entries."""
    memory, trajectory = repeated_failure_memory(
        root, encoder, length=LENGTH, onset=ONSET, failure_frames=failure_frames, successes=False
    )
    trace = FailureDetector(memory, encoder, k=3, rule="paper").run(trajectory)
    fired = trace.with_delta(1.0 - 1e-5)
    report = report_for(fired, trajectory)
    assert report is not None
    return report


def test_a_dense_report_names_the_frame_beside_its_image(tmp_path: Path, encoder: CachedEncoder) -> None:
    report = _report(tmp_path, encoder, "dense")
    top = report.items[0]
    # from the onset on the memory holds every frame of episode 0: the run fires there, matching that moment
    assert report.t_det == ONSET and top.similarity == pytest.approx(1.0, abs=1e-5)
    assert (top.frame, top.length, top.moment) == (ONSET, LENGTH, f"frame {ONSET} of {LENGTH} (25 %)")
    for item in report.items:
        assert item.frame is not None and ONSET <= item.frame < LENGTH and item.length == LENGTH
        assert item.end_image.endswith(f"{item.view}_{item.frame}.png")  # the image is that frame
    markdown = report.to_markdown()
    assert "| matched moment of that run |" in markdown
    for item in report.items:
        assert f"| {item.description} | {item.moment} |" in markdown
    # saved and read back (detect --json, a .rrd), opened where its images are named
    read_back = FailureReport.from_dict(report.to_dict(), roots=report.roots)
    assert [(i.frame, i.length) for i in read_back.items] == [(i.frame, i.length) for i in report.items]
    assert read_back.to_dict() == report.to_dict()
    prompt = report.vlm_messages()[2]["content"]
    assert {
        "type": "text",
        "text": f"Reference Frame at the Matched Moment, frame {ONSET} of {LENGTH} (25 %):",
    } in prompt
    assert {"type": "image", "path": top.end_image} in prompt


def test_the_papers_report_says_end_of_the_run_and_old_reports_read_back(
    tmp_path: Path, encoder: CachedEncoder
) -> None:
    report = _report(tmp_path, encoder, "end")
    assert report.t_det == LENGTH - 1  # the paper's memory knows only the end of episode 0
    assert all(item.frame is None and item.moment == "end of the run" for item in report.items)
    saved = report.to_dict()
    assert all("frame" not in item and "length" not in item for item in saved["neighbors"])  # as before
    assert "| end of the run |" in report.to_markdown()
    prompt = report.vlm_messages()[2]["content"]
    assert {"type": "text", "text": "Reference End Frame (Failure State):"} in prompt
    assert FailureReport.from_dict(saved, roots=saved["roots"]).to_dict() == saved
