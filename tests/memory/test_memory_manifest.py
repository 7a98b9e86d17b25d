"""The typed memory manifest reads and writes the same JSON keys and values as the free dict it replaced."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from robofailring.errors import MemoryFormatError
from robofailring.memory.failure import FailureMemory, MemoryEntry
from robofailring.memory.folder import MANIFEST
from robofailring.memory.manifest import MemoryManifest
from robofailring.memory.stored_calibration import StoredCalibration, StoredRule

# a manifest as build-memory + calibrate write it (keys in that order): calibration keyed by rule name
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
        "method": "split conformal, own episode left out",
        "target_fpr": 0.1,
        "successes": 20,
        "data": "/d",
        "split": None,
        "k": 8,
        "stride": 1,
        "rules": {
            "paper": {"threshold": 0.75, "achieved_fpr": 0.05, "fpr_spread": {"runs": 20}, "runs": 20},
            "contrast": {
                "threshold": 0.125,
                "achieved_fpr": 0.1,
                "band": {"kind": "shift", "runs": 20, "mean": [0.0, 0.5], "scale": [1.0, 1.0]},
                "runs": 19,
            },
        },
    },
}

# the calibration section as robofailring wrote it before it was keyed by rule name
OLD_CALIBRATION: dict[str, Any] = {
    "encoder": "pixels-32",
    "delta": 0.75,
    "gamma": 0.125,
    "eta": None,
    "method": "split conformal, own episode left out",
    "target_fpr": 0.1,
    "achieved_fpr": 0.05,
    "gamma_achieved_fpr": 0.1,
    "eta_achieved_fpr": None,
    "successes": 20,
    "fpr_spread": {"runs": 20},
    "data": "/d",
    "split": None,
    "k": 8,
    "stride": 1,
    "band": {"kind": "shift", "rules": {"contrast": {"runs": 20, "mean": [0.0, 0.5], "scale": [1.0, 1.0]}}},
}


def test_parse_then_write_gives_the_same_json_in_the_same_order(tmp_path: Path) -> None:
    manifest = MemoryManifest.parse(json.loads(json.dumps(WRITTEN)), tmp_path / MANIFEST)
    assert manifest.source == "/d" and manifest.layout == "project" and manifest.split == "train"
    calibration = manifest.calibration
    assert calibration is not None and calibration.k == 8 and list(calibration.rules) == ["paper", "contrast"]
    assert calibration.threshold_for("pixels-32", "paper") == 0.75
    assert calibration.threshold_for("pixels-32", "contrast") == 0.125
    assert calibration.threshold_for("pixels-32", "novelty") is None
    assert calibration.threshold_for("open_clip-ViT-B-32", "paper") is None  # another encoder's
    assert calibration.rules["contrast"].band == {
        "kind": "shift",
        "runs": 20,
        "mean": [0.0, 0.5],
        "scale": [1.0, 1.0],
    }
    written = manifest.to_dict()
    assert written == WRITTEN and list(written) == list(WRITTEN)
    assert list(written["calibration"]) == list(WRITTEN["calibration"])


def test_a_calibration_written_before_rule_names_is_read_into_rules_and_rewritten_keyed_by_name(
    tmp_path: Path,
) -> None:
    older = {**WRITTEN, "calibration": OLD_CALIBRATION}
    manifest = MemoryManifest.parse(json.loads(json.dumps(older)), tmp_path / MANIFEST)
    calibration = manifest.calibration
    assert calibration is not None and calibration.extra == {}
    assert calibration.to_dict() == WRITTEN["calibration"] | {
        "rules": {
            "paper": WRITTEN["calibration"]["rules"]["paper"],
            # the old form had one spread and one run count for all rules
            "contrast": WRITTEN["calibration"]["rules"]["contrast"]
            | {"fpr_spread": {"runs": 20}, "runs": 20},
        }
    }
    eta_only = {
        "encoder": "pixels-32",
        "delta": None,
        "eta": 0.2,
        "eta_achieved_fpr": 0.0,
    }  # success runs only
    read = StoredCalibration.parse(eta_only, tmp_path / MANIFEST)
    assert read.rules == {"novelty": StoredRule(threshold=0.2, achieved_fpr=0.0)}
    for broken, said in (
        ({"encoder": "pixels-32", "delta": "high"}, "calibration 'delta' must be a finite number"),
        ({"encoder": "pixels-32", "delta": None}, "calibration has no rule's threshold"),
        ({"encoder": "pixels-32", "rules": {"paper": {"achieved_fpr": 0.1}}}, "rule 'paper' needs a finite"),
        ({"encoder": "pixels-32", "rules": ["paper"]}, "'rules' must be an object"),
        ({"encoder": "pixels-32", "rules": {}}, "calibration has no rule's threshold"),
    ):
        with pytest.raises(MemoryFormatError, match=said):
            StoredCalibration.parse(broken, tmp_path / MANIFEST)


def test_unknown_keys_wrong_types_and_missing_keys_survive_a_rewrite(tmp_path: Path) -> None:
    older = {
        "format_version": 1,
        "encoder": "pixels-32",
        "dim": 4,
        "count": 0,
        "source": 7,  # a known key with another type: kept, not used
        "future_key": {"a": [1, 2]},
        "calibration": {
            "encoder": "pixels-32",
            "k": "eight",
            "note": "by hand",
            "rules": {"paper": {"threshold": 1, "runs": "all", "why": "by hand"}},
        },
    }
    manifest = MemoryManifest.parse(json.loads(json.dumps(older)), tmp_path / MANIFEST)
    assert manifest.source is None and manifest.extra == {"source": 7, "future_key": {"a": [1, 2]}}
    assert manifest.calibration is not None and manifest.calibration.k is None
    assert manifest.calibration.extra == {"k": "eight", "note": "by hand"}
    assert manifest.calibration.rules["paper"].extra == {"runs": "all", "why": "by hand"}
    assert manifest.to_dict() == older  # no key added (no target_fpr), none dropped
    assert isinstance(manifest.to_dict()["calibration"]["rules"]["paper"]["threshold"], int)  # 1 stays 1


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
    assert loaded.calibrated_threshold("paper") is None
    calibrated = loaded.with_calibration(
        StoredCalibration(
            rules={"paper": StoredRule(threshold=0.5), "contrast": StoredRule(threshold=0.25)},
            encoder="pixels-32",
        )
    )
    assert (
        loaded.calibrated_threshold("paper") is None and calibrated.calibrated_threshold("paper") == 0.5
    )  # a new object
    calibrated.write_manifest(tmp_path / "mem")
    after = json.loads((tmp_path / "mem" / MANIFEST).read_text())
    assert after == before | {"calibration": after["calibration"]}  # created and the rest kept as they were
    assert after["calibration"]["rules"] == {"paper": {"threshold": 0.5}, "contrast": {"threshold": 0.25}}
    again = FailureMemory.load(tmp_path / "mem")
    assert again.calibrated_threshold("paper") == 0.5 and again.calibrated_threshold("contrast") == 0.25
    other = StoredCalibration(
        rules={"paper": StoredRule(threshold=0.5)}, encoder="open_clip-ViT-B-32"
    )  # chosen with another encoder
    assert again.with_calibration(other).calibrated_threshold("paper") is None
