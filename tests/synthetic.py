"""Tiny synthetic datasets written as real PNG files, for tests that need frames nobody else made."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from robofailring import CachedEncoder, FailureMemory, Trajectory, load_dataset, load_encoder, load_trajectory
from robofailring.data.images import write_png
from robofailring.data.model import Outcome
from robofailring.memory.builder import Provenance, build_memories
from robofailring.memory.recipe import MemoryRecipe

VIEWS = ("front", "overhead", "wrist")
TASK_COLOURS = {"pick_cube": (40, 90, 160), "push_cube": (150, 60, 40), "stack_cube": (60, 140, 60)}


def synthetic_frame(
    task: str, symbol: str | None, view: int, t: int, length: int, size: int = 48
) -> np.ndarray:
    """A small scene: task-coloured background, a square whose path depends on the failure label."""
    base = np.array(TASK_COLOURS.get(task, (100, 100, 100)), dtype=np.float32)
    image = np.empty((size, size, 3), dtype=np.float32)
    gradient = np.linspace(0.6, 1.0, size, dtype=np.float32)[:, None, None]
    image[:] = base * gradient
    progress = t / max(length - 1, 1)
    offset = 0 if symbol is None else (sum(map(ord, symbol)) % 5 + 2) * 3
    row = int(8 + progress * (size - 24)) if symbol is None else int(8 + progress * offset)
    col = int(6 + view * 10 + progress * offset) % (size - 12)
    image[row : row + 10, col : col + 10] = (230, 220, 40)
    return image.clip(0, 255).astype(np.uint8)


def write_aha_dataset(
    root: Path,
    *,
    tasks: tuple[str, ...] = ("pick_cube", "push_cube"),
    symbols: tuple[str, ...] = ("grasp_wp2", "rotation_x_wp1", "wrong_object"),
    episodes: int = 2,
    length: int = 6,
    views: tuple[str, ...] = VIEWS,
) -> Path:
    """An AHA FailGen-layout dataset of synthetic frames."""
    for task in tasks:
        for symbol in symbols:
            for episode in range(episodes):
                name = (
                    f"{task}_wrong_object_episode{episode}"
                    if symbol == "wrong_object"
                    else f"{task}_{symbol.rsplit('_wp', 1)[0]}_wp{symbol.rsplit('_wp', 1)[1]}_episode{episode}"
                )
                folder = root / name
                folder.mkdir(parents=True, exist_ok=True)
                for v, view in enumerate(views):
                    for t in range(length):
                        frame = synthetic_frame(task, symbol, v, t + episode, length + episodes)
                        write_png(folder / f"{view}_{t}.png", frame)
    return root


def write_episode(
    folder: Path,
    task: str,
    symbol: str | None,
    *,
    length: int = 6,
    views: tuple[str, ...] = VIEWS,
    layout: str = "subfolders",
    shift: int = 0,
) -> Path:
    """One episode, as view sub-folders of numbered PNGs (ManiSkill style) or AHA `<view>_<i>.png` files."""
    for v, view in enumerate(views):
        target = folder / view if layout == "subfolders" else folder
        target.mkdir(parents=True, exist_ok=True)
        for t in range(length):
            name = f"{t}.png" if layout == "subfolders" else f"{view}_{t}.png"
            write_png(target / name, synthetic_frame(task, symbol, v, t + shift, length + shift))
    return folder


def write_project_dataset(
    root: Path,
    *,
    tasks: tuple[str, ...] = ("pick_cube", "push_cube"),
    symbols: tuple[str, ...] = ("grasp_wp2", "slip_wp3", "wrong_object"),
    episodes: int = 4,
    length: int = 6,
    onset: int | None = None,
    signals: bool = False,
) -> Path:
    """A project-layout dataset (manifest + AHA-style folders) with successes and train/test splits;
    `onset`: every failure's onset frame (None: not recorded, as in manifests from before onsets);
    `signals`: each episode's `signals.npz` as the simulator writes it (`robot_signals`)."""
    import json

    records = []
    for task in tasks:
        for symbol in (*symbols, None):
            for episode in range(episodes):
                kind = "success" if symbol is None else symbol.replace("_wp", "_wp")
                name = (
                    f"{task}_{kind}_episode{episode}"
                    if symbol is None or symbol == "wrong_object"
                    else (
                        f"{task}_{symbol.rsplit('_wp', 1)[0]}_wp{symbol.rsplit('_wp', 1)[1]}_episode{episode}"
                    )
                )
                write_episode(root / name, task, symbol, length=length, layout="aha", shift=episode)
                records.append(
                    {
                        "dir": name,
                        "episode": name,
                        "task": task,
                        "label": symbol,
                        "outcome": "success" if symbol is None else "failure",
                        "split": "train" if episode % 2 == 0 else "test",
                        "views": list(VIEWS),
                    }
                    | ({"onset_frame": onset} if onset is not None and symbol is not None else {})
                    | ({"signals": _write_signals(root / name, symbol, length, episode)} if signals else {})
                )
    manifest = {"format": "robofailring-dataset", "format_version": 1, "fps": 10, "episodes": records}
    (root / "manifest.json").write_text(json.dumps(manifest))
    return root


SIGNAL_RECORD = {
    "gripper_width": {"kind": "state", "names": ["width"]},
    "action": {"kind": "action", "names": ["x", "gripper"]},
}


def robot_signals(symbol: str | None, length: int, episode: int) -> dict[str, np.ndarray]:
    """A run's gripper width and commanded action: the gripper closes half-way through, on the cube
    (0.04 m) in a success, on nothing (0 m) in a `grasp` failure; other failures carry it normally but
    command the arm elsewhere (x). Each episode is a little off the others."""
    t = np.arange(length, dtype=np.float64)
    closing = t >= length // 2
    held = 0.0 if symbol is not None and symbol.startswith("grasp") else 0.04
    width = np.where(closing, held, 0.08) + 0.001 * episode
    drift = 0.0 if symbol is None or symbol.startswith("grasp") else 0.3
    x = 0.1 * t / max(length - 1, 1) + drift * closing + 0.002 * episode
    command = np.where(closing, 0.0, 0.08)
    return {"gripper_width": width[:, None], "action": np.stack([x, command], axis=1)}


def _write_signals(folder: Path, symbol: str | None, length: int, episode: int) -> dict[str, object]:
    np.savez(folder / "signals.npz", **robot_signals(symbol, length, episode))  # type: ignore[arg-type]
    return {"file": "signals.npz", "signals": SIGNAL_RECORD}


def write_repeated_failure(root: Path, *, length: int, onset: int) -> tuple[Path, Path]:
    """A project dataset of two `grasp_wp2` failures of `pick_cube` with a known `onset`, and a new run
    (`<root>/pick_cube_grasp_wp2_episode9`) whose frames are those of the dataset's episode 0: from the
    onset on, its frame t pairs with its first exactly as episode 0's frame t does."""
    data = write_project_dataset(
        root / "data", tasks=("pick_cube",), symbols=("grasp_wp2",), episodes=2, length=length, onset=onset
    )
    return data, write_episode(root / "pick_cube_grasp_wp2_episode9", "pick_cube", "grasp_wp2", length=length)


def repeated_failure_memory(
    root: Path,
    encoder: CachedEncoder,
    *,
    length: int,
    onset: int,
    failure_frames: str,
    successes: bool = True,
) -> tuple[FailureMemory, Trajectory]:
    """`write_repeated_failure`'s memory (of `failure_frames`) and its new run, loaded."""
    data, episode = write_repeated_failure(root, length=length, onset=onset)
    memory, _ = build_memories(
        list(load_dataset(data)),
        encoder,
        provenance=Provenance(data=data, encoder="pixels"),
        successes=successes,
        recipe=MemoryRecipe(failure_frames=failure_frames),
    )
    return memory, load_trajectory(episode)


def write_labelled_runs(
    root: Path,
    *,
    runs: int = 14,
    task: str = "pick_cube",
    length: int = 8,
    views: tuple[str, ...] = ("front", "wrist"),
) -> tuple[Path, Path]:
    """`runs` image episodes `run_<i>` (`<view>_<t>.png`) whose names say neither task nor outcome, every
    other one a failure (`grasp_wp2`, `slip_wp3` in turn), and a labels CSV with a `task` column beside
    `root`: what a user with a handful of labelled rollouts has. Returns (root, labels file)."""
    import csv

    rows = []
    for run in range(runs):
        symbol = ("grasp_wp2", "slip_wp3")[run // 2 % 2] if run % 2 else None
        folder = root / f"run_{run:02d}"
        folder.mkdir(parents=True, exist_ok=True)
        for v, view in enumerate(views):
            for t in range(length):
                write_png(
                    folder / f"{view}_{t}.png",
                    synthetic_frame(task, symbol, v, t + run % 3, length + run % 3),
                )
        rows.append(
            {
                "episode": folder.name,
                "outcome": "failure" if symbol else "success",
                "symbol": symbol or "",
                "task": task,
            }
        )
    labels = root.parent / f"{root.name}-labels.csv"
    with labels.open("w", newline="", encoding="utf-8") as file:
        writer = csv.DictWriter(file, fieldnames=["episode", "outcome", "symbol", "task"])
        writer.writeheader()
        writer.writerows(rows)
    return root, labels


def write_unlabelled_runs(
    root: Path,
    *,
    successes: int = 13,
    failures: tuple[str, ...] = ("grasp_wp2", "no_rotation_wp1", "rotation_x_wp1"),
    task: str = "pick_cube",
    length: int = 6,
    views: tuple[str, ...] = ("front", "wrist"),
    size: int = 32,
) -> tuple[Path, dict[str, str]]:
    """Image episodes `run_<i>` whose names say neither task nor outcome: `successes` normal runs (each
    like some other one: four starting offsets, and a little noise of its own) and one run per symbol
    of `failures` (these three move differently from each other), spread among them. Returns the root
    and the truth (`success` or the failure's symbol) by episode name."""
    kinds: list[str | None] = [None] * successes
    for position, symbol in enumerate(failures):
        kinds.insert(min(len(kinds), 3 + position * 5), symbol)
    truth = {}
    for run, symbol in enumerate(kinds):
        folder = root / f"run_{run:02d}"
        folder.mkdir(parents=True, exist_ok=True)
        shift = run % 4 if symbol is None else 1
        for v, view in enumerate(views):
            for t in range(length):
                frame = synthetic_frame(task, symbol, v, t + shift, length + shift, size=size).astype(
                    np.int16
                )
                noise = np.random.default_rng([run, v, t]).integers(-3, 4, frame.shape)
                write_png(folder / f"{view}_{t}.png", (frame + noise).clip(0, 255).astype(np.uint8))
        truth[folder.name] = symbol or "success"
    return root, truth


def write_triage_memory(root: Path) -> Path:
    """A pixels memory of task pick_cube saved in `root / "memory"`: 4 known-good runs and one failure
    (`grasp_wp2`) written as unlabelled image runs in `root / "known"`, labelled here."""
    known, _ = write_unlabelled_runs(root / "known", successes=4, failures=("grasp_wp2",))
    failed = {"outcome": Outcome.FAILURE, "symbol": "grasp_wp2"}
    labelled = [
        replace(t, **(failed if t.episode == "run_03" else {"outcome": Outcome.SUCCESS}))
        for t in load_dataset(known, task="pick_cube")
    ]
    encoder = CachedEncoder(load_encoder("pixels"), cache_dir=root / "cache")
    memory, _ = build_memories(labelled, encoder, provenance=Provenance(data=known, encoder="pixels"))
    return memory.save(root / "memory")


def csv_rows(path: Path) -> list[dict[str, str]]:
    """A labels file or a triage table read back as rows, one dict per row by its header."""
    import csv

    with path.open(newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def data_root_of(memory: Path) -> str:
    """The data root a memory records: the folder a user names (--data-root) for its images."""
    return str(json.loads((memory / "manifest.json").read_text())["data_root"])
