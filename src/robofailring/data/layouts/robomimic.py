"""robomimic-style HDF5 (robomimic, LIBERO, RoboCasa, MimicGen): a file, or a folder of files, one trajectory per demo.

`data/demo_<i>/obs/<camera>_image` (LIBERO: `<camera>_rgb`) as (N, H, W, 3) uint8 is view `<camera>`;
`data` attributes hold `env_args` (JSON) and, in LIBERO, `problem_info` (JSON with the
`language_instruction`, the task); `mask/<split>` lists demo names, used as splits. Trajectories are
keyed by the demo's name (`demo_3`); low-dim `obs/<key>` arrays and `actions` are its signals; frames are rows sliced on demand, LIBERO's bottom-up rows
(`data` attribute `macros_image_convention` = `opengl`) flipped upright. The task: `--task`, else
LIBERO's instruction, else `env_args`'s `env_name`.

A folder whose HDF5 files are mostly robomimic-style is a dataset of them (LIBERO's suite folder of
`<task>_demo.hdf5`, MimicGen's `demo.hdf5` beside `demo_failed.hdf5`); with more than one such file
its trajectories are keyed `<file stem>/demo_<i>`, and what else the folder holds is listed as not
read. Outcome and symbol come from `--labels`, except that the demos of a file named
`demo_failed.hdf5` (MimicGen's failed attempts) are failures without a symbol unless labelled.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any, Final

from robofailring.data.grounding import UNTYPED
from robofailring.data.hdf5 import (
    HDF5Frames,
    describe,
    hdf5_faults,
    is_hdf5,
    is_image_array,
    open_hdf5,
    row_format,
    unreadable,
)
from robofailring.data.layouts.folders import natural_key, visible
from robofailring.data.layouts.hdf5_signals import robomimic_signals
from robofailring.data.layouts.registry import Found, Layout, register
from robofailring.data.model import Frame, Outcome, Skipped, Trajectory
from robofailring.errors import DataError
from robofailring.jsontext import parse_json

_IMAGE_SUFFIXES: Final[tuple[str, ...]] = ("_image", "_rgb")
_SPLIT_ORDER: Final[tuple[str, ...]] = ("train", "valid", "test")
SHAPE: Final[str] = "data/demo_<i>/obs/<camera>_image (N, H, W, 3) uint8"
FAILED_FILE: Final[str] = "demo_failed"  # MimicGen's file of failed generation attempts


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
    loaded = parse_json(text, source=f"{where}: attribute {name!r}")
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


def is_robomimic_file(path: Path) -> bool:
    """An HDF5 file whose `data` group holds `demo*` groups (whether they have images is not checked)."""
    if not is_hdf5(path):
        return False
    try:
        with hdf5_faults(path):
            data = open_hdf5(path).get("data")
            return data is not None and hasattr(data, "keys") and any(key.startswith("demo") for key in data)
    except DataError:
        return False


def robomimic_trajectories(root: Path, *, task: str | None = None) -> Found:
    """Every demo of a robomimic-style file, or of each such file of a folder; what is not read is listed."""
    if root.is_file():
        with hdf5_faults(root):
            return _file_trajectories(root, task=task, prefix="")
    entries = visible(root)
    files = [path for path in entries if is_robomimic_file(path)]
    skipped = [
        Skipped(path, (is_hdf5(path) and unreadable(path)) or f"not a robomimic-style HDF5 file ({SHAPE})")
        for path in entries
        if path not in files
    ]
    found: list[Trajectory] = []
    for path in files:
        try:
            with hdf5_faults(path):
                demos, inside = _file_trajectories(
                    path, task=task, prefix=f"{path.stem}/" if len(files) > 1 else ""
                )
        except DataError as error:  # a file of the structure without image observations (low_dim.hdf5)
            skipped.append(Skipped(path, f"not read: {error}"))
            continue
        found += demos
        skipped += inside
    if not found:
        raise DataError(
            f"{root}: no robomimic-style HDF5 file in it has a demo with an image observation ({SHAPE}); "
            + "; ".join(f"{s.path.name}: {s.reason}" for s in skipped[:3])
        )
    return found, skipped


def _file_trajectories(root: Path, *, task: str | None, prefix: str) -> Found:
    """Every demo of one file, keyed `<prefix><demo>`; image-like arrays that are not RGB are listed as skipped."""
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
    failed = root.stem == FAILED_FILE
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
                episode=f"{prefix}{demo}",
                views=views,
                symbol=UNTYPED if failed else None,
                outcome=Outcome.FAILURE if failed else None,
                source=root,
                fps=float(fps) if isinstance(fps, (int, float)) else None,
                split=splits.get(demo),
                signals=robomimic_signals(root, data[demo], demo),
            )
        )
    if not found:
        raise DataError(
            f"HDF5 file {root}: no demo has an image observation ({SHAPE}); it holds: {describe(handle)}"
        )
    return found, list(skipped.values())


def _detect(root: Path) -> bool:
    """One HDF5 file, or a folder where more than half of the HDF5 files are robomimic-style."""
    if root.is_file():
        return is_hdf5(root)
    files = [path for path in visible(root) if is_hdf5(path)]
    return 2 * sum(map(is_robomimic_file, files)) > len(files)


LAYOUT: Final = register(
    Layout(
        name="robomimic",
        detect=_detect,
        read=robomimic_trajectories,
        help=f"a robomimic/LIBERO HDF5 file ({SHAPE}, mask/<split>), or a folder of them",
        listed=8,
        detect_order=50,  # any one HDF5 file: after the HDF5 layouts of a stricter shape
        reads_files=True,
    )
)
