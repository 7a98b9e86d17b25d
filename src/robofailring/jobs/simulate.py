"""The extra simulated sets an encoder trains on beside its data (`train-encoder --randomize`), cached under
the robofailring cache dir in folders named by their content."""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Final

from robofailring.encoders import default_cache_dir
from robofailring.errors import SettingError
from robofailring.sim import KINDS, GenerateConfig, simulate

EXTRA_SETS: Final[str] = "encoder-extra-data"  # under the robofailring cache dir


@dataclass(frozen=True)
class DataShape:
    """What a simulated set must match to train beside a dataset: its tasks, image side and frames."""

    tasks: tuple[str, ...]
    image_size: int
    frames: int


def extra_set(
    shape: DataShape,
    episodes: int,
    *,
    look: str,
    seed: int,
    workers: int = 2,
    cache: Path | None = None,
) -> Path:
    """`episodes` simulated episodes of `shape` under `look`, spread over its tasks and every failure
    family and success in equal shares (rounded to a whole number per task and kind), simulated once
    and cached in a folder of `cache` (default <cache>/encoder-extra-data) named by their content."""
    if episodes < 1:
        raise SettingError(f"an extra simulated set needs at least 1 episode, got {episodes}")
    per_kind = max(1, int(episodes / (len(shape.tasks) * len(KINDS)) + 0.5))
    config = GenerateConfig(
        out=Path(),
        tasks=shape.tasks,
        episodes=per_kind,
        seed=seed,
        look=look,
        image_size=shape.image_size,
        frames=shape.frames,
        workers=workers,
    )
    key = hashlib.blake2b(json.dumps(config.content(), sort_keys=True).encode(), digest_size=8).hexdigest()
    folder = (cache or default_cache_dir() / EXTRA_SETS) / f"{look}-{key}"
    return simulate(replace(config, out=folder), label=f"{look} looks")
