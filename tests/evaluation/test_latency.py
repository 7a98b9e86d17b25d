"""The latency table is honest (issue 32, item 6): it said "encoder 5.32 ms, retrieval 0.000 ms, total
2.70 ms" because the encode and the whole step were two separate timings of two separate encodes."""

from __future__ import annotations

from pathlib import Path

from robofailring import FailureDetector, FailureMemory, load_dataset, load_encoder
from robofailring.evaluation.latency import measure_latency


def test_each_steps_total_is_its_encode_plus_its_retrieval(
    aha_dataset: Path, pixels_memory: FailureMemory
) -> None:
    trajectory = next(iter(load_dataset(aha_dataset)))
    detector = FailureDetector(pixels_memory, load_encoder("pixels"))
    found = measure_latency(detector, trajectory, frames=6)
    assert set(found) == {"encode", "retrieval", "total"}
    assert found["encode"] > 0 and found["retrieval"] > 0  # a search of a real Faiss index takes time
    assert found["total"] >= max(found["encode"], found["retrieval"])
