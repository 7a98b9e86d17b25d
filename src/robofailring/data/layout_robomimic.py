"""robomimic-style HDF5 (robomimic, LIBERO, RoboCasa, MimicGen): one file, one trajectory per demo.

`data/demo_<i>/obs/<camera>_image` (LIBERO: `<camera>_rgb`) as (N, H, W, 3) uint8 is view `<camera>`;
`data` attributes hold `env_args` (JSON) and, in LIBERO, `problem_info` (JSON with the
`language_instruction`, the task); `mask/<split>` lists demo names, used as splits. Trajectories are
keyed by the demo's name (`demo_3`); frames are rows sliced on demand, LIBERO's bottom-up rows
(`data` attribute `macros_image_convention` = `opengl`) flipped upright. Outcome and symbol come from
`--labels`. The task: `--task`, else LIBERO's instruction, else `env_args`'s `env_name`.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Final

from robofailring.data.folders import natural_key
from robofailring.data.hdf5 import HDF5Frames, describe, is_hdf5, is_image_array, open_hdf5, row_format
from robofailring.data.model import Frame, Skipped, Trajectory
from robofailring.data.registry import Found, Layout, register
from robofailring.errors import DataError

_IMAGE_SUFFIXES: Final[tuple[str, ...]] = ("_image", "_rgb")
_SPLIT_ORDER: Final[tuple[str, ...]] = ("train", "valid", "test")
SHAPE: Final[str] = "data/demo_<i>/obs/<camera>_image (N, H, W, 3) uint8"


def view_name(key: str) -> str:
    """`agentview_image` → `agentview`, LIBERO's `eye_in_hand_rgb` → `eye_in_hand`."""
    for suffix in _IMAGE_SUFFIXES:
        if key.endswith(suffix) and len(key) > len(suffix):
            return key[: -len(suffix)]
    return key


def _json_attr(group: Any, name: str, where: str) -> dict[str, Any]:
    raw = group.attrs.get(name)
    if raw is None:
        return {}
    text = raw.decode() if isinstance(raw, bytes) else str(raw)
    try:
        loaded = json.loads(text)
    except json.JSONDecodeError as error:
        raise DataError(f"{where}: attribute {name!r} is not valid JSON ({error})") from error
    return loaded if isinstance(loaded, dict) else {}


def _splits(handle: Any) -> dict[str, str]:
    """Each demo's split from `mask/<split>` (train, valid, test first; then the others by name)."""
    masks = handle.get("mask")
    if masks is None:
        return {}
    names = sorted(masks.keys(), key=lambda n: (_SPLIT_ORDER.index(n) if n in _SPLIT_ORDER else 9, n))
    found: dict[str, str] = {}
    for name in names:
        for demo in masks[name][()]:
            found.setdefault(demo.decode() if isinstance(demo, bytes) else str(demo), name)
    return found


def _task(data: Any, root: Path, task: str | None) -> str:
    problem = _json_attr(data, "problem_info", f"{root} /data")
    instruction = problem.get("language_instruction")
    env = _json_attr(data, "env_args", f"{root} /data")
    for found in (task, instruction, env.get("env_name")):
        if isinstance(found, str) and found.strip():
            return found.strip()
    return root.stem


def robomimic_trajectories(root: Path, *, task: str | None = None) -> Found:
    """Every demo of a robomimic-style file; image-like arrays that are not RGB are listed as skipped."""
    handle = open_hdf5(root)
    data = handle.get("data")
    demos = (
        sorted((k for k in data if k.startswith("demo")), key=lambda k: natural_key(Path(k)))
        if (data is not None and hasattr(data, "keys"))
        else []
    )
    if not demos:
        raise DataError(
            f"HDF5 file {root} is not robomimic-style ({SHAPE}) nor an ALOHA episode "
            f"(observations/images/<cam>); it holds: {describe(handle)}"
        )
    name = _task(data, root, task)
    fps = _json_attr(data, "env_args", f"{root} /data").get("env_kwargs", {}).get("control_freq")
    splits = _splits(handle)
    found: list[Trajectory] = []
    skipped: dict[str, Skipped] = {}
    for demo in demos:
        obs = data[demo].get("obs")
        views: dict[str, Sequence[Frame]] = {}
        for key in obs.keys() if obs is not None else ():
            item = obs[key]
            if is_image_array(item):
                dataset = f"/data/{demo}/obs/{key}"
                views[view_name(key)] = HDF5Frames(
                    root, dataset, int(item.shape[0]), form=row_format(handle, dataset)
                )
            elif hasattr(item, "shape") and len(item.shape) in (3, 4):
                skipped.setdefault(
                    key,
                    Skipped(
                        root,
                        f"obs/{key} {tuple(item.shape)} {item.dtype} is not an RGB image (N, H, W, 3) "
                        "uint8: not read",
                    ),
                )
        if not views:
            skipped[demo] = Skipped(
                root, f"/data/{demo} has no obs/<camera>_image (N, H, W, 3) uint8: not read"
            )
            continue
        found.append(
            Trajectory(
                task=name,
                episode=demo,
                views=views,
                source=root,
                fps=float(fps) if isinstance(fps, (int, float)) else None,
                split=splits.get(demo),
            )
        )
    if not found:
        raise DataError(
            f"HDF5 file {root}: no demo has an image observation ({SHAPE}); it holds: {describe(handle)}"
        )
    return found, list(skipped.values())


def _detect(root: Path) -> bool:
    return is_hdf5(root)


LAYOUT: Final = register(
    Layout(
        name="robomimic",
        detect=_detect,
        read=robomimic_trajectories,
        help=f"a robomimic/LIBERO HDF5 file ({SHAPE}, mask/<split>)",
        listed=8,
        reads_files=True,
        outcomes_in_data=False,
    )
)
