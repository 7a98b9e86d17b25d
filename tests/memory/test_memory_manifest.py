"""The typed memory manifest reads and writes the same JSON keys and values as the free dict it replaced."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from robofailring.memory.failure import MANIFEST, FailureMemory, MemoryEntry
from robofailring.memory.manifest import MemoryManifest, StoredCalibration

# a manifest as build-memory + calibrate wrote it before the typed manifest (keys in that order)
WRITTEN: dict[str, Any] = {
    "dim": 4,
    "skipped_views": 1,
    "skipped": [{"episode": "e9", "view": "front", "frames": 1}],
    "failures": 2,
    "ignored_non_failures": 3,
    "skipped_inputs": [{"path": "/d/x", "reason": "no frames"}],
    "source": "/d",
    "layout": "project",
    "encoder_spec": "pixels",
    "split": "train",
    "data_root": "/d",
    "format_version": 2,
    "encoder": "pixels-32",
    "count": 2,
    "tasks": {"t": 2},
    "views": ["front"],
    "symbols": {"slip_wp3": 2},
    "successes": {"count": 5, "runs": 1, "tasks": {"t": 5}},
    "created": "2026-01-01T00:00:00+00:00",
    "calibration": {
        "encoder": "pixels-32",
        "delta": 0.75,
        "gamma": None,
        "method": "split conformal, own episode left out",
        "target_fpr": 0.1,
        "achieved_fpr": 0.05,
        "gamma_achieved_fpr": None,
        "successes": 20,
        "data": "/d",
        "split": None,
        "k": 8,
        "stride": 1,
    },
}


def test_parse_then_write_gives_the_same_json_in_the_same_order(tmp_path: Path) -> None:
    manifest = MemoryManifest.parse(json.loads(json.dumps(WRITTEN)), tmp_path / MANIFEST)
    assert manifest.source == "/d" and manifest.layout == "project" and manifest.split == "train"
    assert manifest.calibration is not None and manifest.calibration.delta == 0.75
    assert manifest.calibration.gamma is None and manifest.calibration.k == 8
    written = manifest.to_dict()
    assert written == WRITTEN and list(written) == list(WRITTEN)
    assert list(written["calibration"]) == list(WRITTEN["calibration"])


def test_unknown_keys_wrong_types_and_missing_keys_survive_a_rewrite(tmp_path: Path) -> None:
    older = {
        "format_version": 1,
        "encoder": "pixels-32",
        "dim": 4,
        "count": 0,
        "source": 7,  # a known key with another type: kept, not used
        "future_key": {"a": [1, 2]},
        "calibration": {"encoder": "pixels-32", "delta": 1, "k": "eight", "note": "by hand"},
    }
    manifest = MemoryManifest.parse(json.loads(json.dumps(older)), tmp_path / MANIFEST)
    assert manifest.source is None and manifest.extra == {"source": 7, "future_key": {"a": [1, 2]}}
    assert manifest.calibration is not None and manifest.calibration.k is None
    assert manifest.calibration.extra == {"k": "eight", "note": "by hand"}
    assert manifest.to_dict() == older  # no key added (no gamma, no target_fpr), none dropped
    assert isinstance(manifest.to_dict()["calibration"]["delta"], int)  # 1 stays 1, not 1.0


def test_a_saved_memory_rewrites_its_manifest_unchanged_and_reads_the_typed_calibration(
    tmp_path: Path,
) -> None:
    entries = [
        MemoryEntry(task="t", symbol="slip_wp3", episode=f"e{i}", view="front", start="a.png", end="b.png")
        for i in range(2)
    ]
    vectors = np.eye(2, 4, dtype=np.float32)
    manifest = MemoryManifest(encoder="pixels-32", dim=4, source=str(tmp_path))
    memory = FailureMemory(vectors, entries, encoder="pixels-32", manifest=manifest)
    memory.save(tmp_path / "mem")
    before = json.loads((tmp_path / "mem" / MANIFEST).read_text())
    assert before["source"] == str(tmp_path) and before["count"] == 2 and "calibration" not in before
    loaded = FailureMemory.load(tmp_path / "mem")
    assert loaded.calibrated_delta is None
    calibrated = loaded.with_calibration(StoredCalibration(delta=0.5, encoder="pixels-32", gamma=0.25))
    assert loaded.calibrated_delta is None and calibrated.calibrated_delta == 0.5  # a new object
    calibrated.write_manifest(tmp_path / "mem")
    after = json.loads((tmp_path / "mem" / MANIFEST).read_text())
    assert after == before | {"calibration": after["calibration"]}  # created and the rest kept as they were
    assert after["calibration"]["delta"] == 0.5 and after["calibration"]["gamma"] == 0.25
    again = FailureMemory.load(tmp_path / "mem")
    assert again.calibrated_delta == 0.5 and again.calibrated_gamma == 0.25
    other = StoredCalibration(delta=0.5, encoder="open_clip-ViT-B-32")  # chosen with another encoder
    assert again.with_calibration(other).calibrated_delta is None
