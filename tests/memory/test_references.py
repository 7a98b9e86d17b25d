"""A memory that travels: image references resolve from any working directory, moved data re-roots."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from rrd import rows
from synthetic import write_aha_dataset
from typer.testing import CliRunner

from rfr_viz.cli.app import app
from robofailring.memory.failure import FailureMemory
from robofailring.memory.folder import ENTRIES, MANIFEST
from robofailring.memory.references import check_references, reroot, resolve_stored, to_stored
from robofailring.memory.stored_calibration import StoredCalibration, StoredRule

TASKS = ("pick_cube",)
SYMBOLS = ("grasp_wp2", "rotation_x_wp1")
EPISODE = "pick_cube_grasp_wp2_episode1"


def test_stored_references_are_relative_under_the_root_and_absolute_outside(tmp_path: Path) -> None:
    root = tmp_path / "data"
    inside = str(root / "ep" / "front_0.png")
    outside = str(tmp_path / "elsewhere" / "front_0.png")
    assert to_stored(inside, root) == "ep/front_0.png"
    assert to_stored(outside, root) == outside
    assert to_stored("<array>", root) == "<array>"
    assert resolve_stored("ep/front_0.png", root) == inside
    assert resolve_stored(outside, tmp_path / "other") == outside
    assert reroot(inside, root, tmp_path / "moved") == str(tmp_path / "moved" / "ep" / "front_0.png")
    assert reroot(outside, root, tmp_path / "moved") == outside


def test_check_references_counts_distinct_missing_files(tmp_path: Path) -> None:
    present = tmp_path / "a.png"
    present.write_bytes(b"x")
    check = check_references([str(present), str(present), str(tmp_path / "b.png"), "<array>"])
    assert (check.total, check.found, check.missing) == (2, 1, (str(tmp_path / "b.png"),))
    assert "1 of 2 reference image(s)" in check.summary()
    assert check_references([str(present)]).summary() == ""
    video = tmp_path / "front.mp4"
    video.write_bytes(b"x")
    frames = check_references([f"{video}#frame=3", f"{tmp_path / 'gone.mp4'}#frame=0"])
    assert frames.missing == (f"{tmp_path / 'gone.mp4'}#frame=0",)


def _invoke(args: list[str]) -> tuple[int, str, str]:
    result = CliRunner().invoke(app, args)
    return result.exit_code, result.stdout, result.stderr


@pytest.fixture()
def relative_build(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> tuple[Path, Path]:
    """`build-memory data/aha --out mem` run inside `<tmp>/build` with a relative data path."""
    build_dir = tmp_path / "build"
    write_aha_dataset(build_dir / "data" / "aha", tasks=TASKS, symbols=SYMBOLS, episodes=2)
    monkeypatch.chdir(build_dir)
    code, out, err = _invoke(
        ["build-memory", "data/aha", "--out", "mem", "--cache-dir", str(tmp_path / "cache")]
    )
    assert code == 0, out + err
    return build_dir / "data" / "aha", build_dir / "mem"


def _neighbor_images(recording: Path) -> list[np.ndarray]:
    found = []
    for _, blob in rows(recording, "/neighbors/front/0/end", "EncodedImage:blob"):
        data = np.asarray(blob[0] if isinstance(blob, list) else blob, dtype=np.uint8)
        found.append(cv2.imdecode(data, cv2.IMREAD_COLOR))
    return found


def _info_texts(recording: Path) -> list[str]:
    return [str(text) for _, text in rows(recording, "/neighbors/front/0/info", "TextDocument:text")]


def _replay(data: Path, memory: Path, out: Path, *extra: str) -> tuple[int, str, str, Path]:
    code, stdout, stderr = _invoke(
        ["replay", str(data), "--memory", str(memory), "--out", str(out), "--trajectory", EPISODE, *extra]
    )
    recordings = sorted(out.glob("*.rrd"))
    assert len(recordings) == 1, stdout + stderr
    return code, stdout, stderr, recordings[0]


def test_relative_build_resolves_from_another_folder(
    relative_build: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    data, memory_dir = relative_build
    manifest = json.loads((memory_dir / MANIFEST).read_text())
    assert manifest["data_root"] == str(data.resolve())
    stored = [json.loads(line) for line in (memory_dir / ENTRIES).read_text().splitlines()]
    assert all(not Path(row["start"]).is_absolute() for row in stored)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    memory = FailureMemory.load(memory_dir)
    assert memory.check_references().ok
    assert memory.entries[0].start == str(data.resolve() / stored[0]["start"])
    code, stdout, stderr, recording = _replay(data, memory_dir, elsewhere / "rec")
    assert code == 0, stdout + stderr
    assert "not found" not in stderr
    images = _neighbor_images(recording)
    assert images and all(image.shape == (48, 48, 3) for image in images)
    assert not any("image not" in text for text in _info_texts(recording))


def test_moved_data_is_reported_missing_then_rerooted(
    relative_build: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    data, memory_dir = relative_build
    moved = tmp_path / "disk2" / "aha"
    moved.parent.mkdir()
    shutil.move(str(data), moved)
    monkeypatch.chdir(tmp_path)
    entries = FailureMemory.load(memory_dir).check_references()
    code, _, stderr, recording = _replay(moved, memory_dir, tmp_path / "lost")
    assert code == 0
    assert f"{len(entries.missing)} of {entries.total} reference image(s)" in stderr
    assert str(data.resolve()) in stderr and "--data-root" in stderr
    # where it was: outside the data replayed, so not even looked at (a recording never says which exist)
    assert any("image not read" in text and str(data.resolve()) in text for text in _info_texts(recording))
    placeholders = _neighbor_images(recording)
    # no image of the memory is found, so the grid keeps its default 256 px cell: grey with white text
    assert placeholders and all(image.shape[:2] == (256, 256) for image in placeholders)
    assert all(abs(np.median(image) - 96) <= 2 and (image > 200).mean() > 0.005 for image in placeholders)

    code, _, stderr, recording = _replay(moved, memory_dir, tmp_path / "found", "--data-root", str(moved))
    assert code == 0
    assert "not found" not in stderr
    assert not any("image not" in text for text in _info_texts(recording))
    rerooted = FailureMemory.load(memory_dir, data_root=moved)
    assert all(Path(entry.end).is_relative_to(moved) for entry in rerooted.entries)

    code, stdout, _ = _invoke(["memory-info", str(memory_dir), "--json"])
    info = json.loads(stdout)
    assert info["references"]["found"] == 0 and info["references"]["missing"] == entries.total
    code, stdout, _ = _invoke(["memory-info", str(memory_dir), "--data-root", str(moved), "--json"])
    info = json.loads(stdout)
    assert code == 0
    assert info["references"] == {
        "total": entries.total,
        "found": entries.total,
        "missing": 0,
        "first_missing": None,
    }
    assert info["data_root"] == str(data.resolve()) and info["data_root_used"] == str(moved.resolve())
    assert info["tasks"] == {
        "pick_cube": {"front": 19, "overhead": 19, "wrist": 19}
    }  # dense: frames 1-5 of 4 runs, less one run's frame 1, where its square has not yet moved from frame 0
    assert (info["failure_frames"], info["failure_step"]) == ("dense", 0.002)


def test_memory_info_text(relative_build: tuple[Path, Path]) -> None:
    data, memory_dir = relative_build
    code, stdout, stderr = _invoke(["memory-info", str(memory_dir)])
    assert code == 0, stderr
    assert f"data root   {data.resolve()}" in stdout
    assert "69 of 69 reference images found" in stdout  # 19 entries per view and 4 first frames, × 3 views
    assert "57 × 1024-d over 1 task(s)" in stdout
    assert (
        "failures    dense, 57 entries from 12 failure views" in stdout and "thinned at step 0.002" in stdout
    )
    assert "pick_cube  front 19, overhead 19, wrist 19" in stdout
    assert "thresholds  not calibrated (each rule's default)" in stdout and "successes   none" in stdout


def test_memory_info_names_each_calibrated_rule(relative_build: tuple[Path, Path], tmp_path: Path) -> None:
    _, memory_dir = relative_build
    copy = tmp_path / "memory"
    shutil.copytree(memory_dir, copy)
    loaded = FailureMemory.load(copy)
    rules = {"paper": StoredRule(threshold=0.875), "mine": StoredRule(threshold=0.125)}
    loaded.with_calibration(StoredCalibration(rules=rules, encoder=loaded.encoder)).write_manifest(copy)
    code, stdout, stderr = _invoke(["memory-info", str(copy), "--json"])
    assert code == 0, stderr
    assert json.loads(stdout)["calibrated_thresholds"] == {"paper": 0.875, "mine": 0.125}
    code, stdout, stderr = _invoke(["memory-info", str(copy)])
    assert "thresholds  calibrated: paper 0.875000, mine 0.125000" in stdout


def test_old_format_memory_still_resolves_and_reroots(
    relative_build: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A format-1 memory stored references as given (relative to the build's working directory)."""
    data, memory_dir = relative_build
    build_dir = data.parent.parent
    old = tmp_path / "old-mem"
    shutil.copytree(memory_dir, old)
    manifest = json.loads((old / MANIFEST).read_text())
    manifest["format_version"] = 1
    del manifest["data_root"]
    (old / MANIFEST).write_text(json.dumps(manifest))
    rows_ = [json.loads(line) for line in (old / ENTRIES).read_text().splitlines()]
    for row in rows_:
        row["start"], row["end"] = f"data/aha/{row['start']}", f"data/aha/{row['end']}"
    (old / ENTRIES).write_text("".join(json.dumps(row) + "\n" for row in rows_))

    monkeypatch.chdir(build_dir)
    memory = FailureMemory.load(old)
    assert memory.entries[0].start == rows_[0]["start"]  # as stored, resolving against the build's cwd
    assert memory.check_references().ok

    moved = tmp_path / "moved"
    shutil.copytree(data, moved)
    monkeypatch.chdir(tmp_path)
    assert not FailureMemory.load(old).check_references().ok
    rerooted = FailureMemory.load(old, data_root=moved)
    assert rerooted.check_references().ok
    assert rerooted.entries[0].start == str(moved.resolve() / rows_[0]["start"].removeprefix("data/aha/"))


def test_report_names_missing_images(relative_build: tuple[Path, Path]) -> None:
    from robofailring.explain.report import FailureReport

    _, memory_dir = relative_build
    memory = FailureMemory.load(memory_dir)
    sims, ids = memory.search(memory.vectors[:1], "pick_cube", 2)
    report = FailureReport.from_neighbors(
        task="pick_cube", view="front", t_det=3, neighbors=memory.neighbors(sims[0], ids[0])
    )
    assert report.missing_images() == []
    Path(report.items[0].end_image).unlink()
    assert report.missing_images() == [report.items[0].end_image]
    assert f"**image not found:** `{report.items[0].end_image}`" in report.to_markdown()


def test_vlm_is_not_asked_without_its_images_and_explain_reroots(
    relative_build: tuple[Path, Path], tmp_path: Path
) -> None:
    from vlm_server import ANSWER, chat_server

    from robofailring.explain.report import FailureReport
    from robofailring.explain.vlm import VLMConfig, ask_vlm

    data, memory_dir = relative_build
    memory = FailureMemory.load(memory_dir)
    sims, ids = memory.search(memory.vectors[:1], "pick_cube", 2)
    report = FailureReport.from_neighbors(
        task="pick_cube", view="front", t_det=3, neighbors=memory.neighbors(sims[0], ids[0])
    )
    moved = tmp_path / "disk2" / "aha"
    moved.parent.mkdir()
    shutil.move(str(data), moved)
    with chat_server() as server:
        config = VLMConfig(url=server.url, model="m", retries=0)
        answer = ask_vlm(report, config)
        assert answer.answer is None and answer.error is not None
        assert "not sent: 2 report image(s) not found" in answer.error and "--data-root" in answer.error
        assert server.received == []  # nothing went over the wire
        relocated = report.relocated(moved)
        assert relocated.items[0].end_image == str(moved / Path(report.items[0].end_image).relative_to(data))
        assert relocated.missing_images() == []
        assert ask_vlm(relocated, config).answer == ANSWER
        assert len(server.received) == 1
