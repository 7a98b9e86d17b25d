"""Folder names are user input: the AHA and ManiSkill layouts read any name as an episode whose symbol
grounds (or is refused with SymbolError), or skip it with a reason; never another exception, and never
a folder dropped without a word."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from hypothesis import assume, example, given
from hypothesis import strategies as st

from robofailring.data.grounding import parse_symbol
from robofailring.data.images import write_png
from robofailring.data.layouts.aha import AHA_FAILURES, aha_name_problem, aha_trajectories, parse_aha_name
from robofailring.data.layouts.maniskill import MANISKILL_FAILURES, MANISKILL_SUCCESS, maniskill_trajectories
from robofailring.data.model import Skipped, Trajectory
from robofailring.errors import SymbolError

PARTS = st.one_of(
    st.sampled_from(
        [
            *AHA_FAILURES,
            *MANISKILL_FAILURES,
            MANISKILL_SUCCESS,
            "wrong_object",
            "success",
            "episode",
            "wp",
            "stage",
        ]
    ),
    st.from_regex(r"(wp|episode|stage)?[0-9]{1,4}", fullmatch=True),
    st.text(st.characters(codec="utf-8", exclude_characters="/\0"), min_size=1, max_size=8),
)
NAMES = st.one_of(
    st.text(st.characters(codec="utf-8", exclude_characters="/\0"), min_size=1, max_size=30),
    st.lists(PARTS, min_size=1, max_size=5).map("_".join),
).filter(lambda name: name not in (".", "..") and len(name.encode()) < 200)


def _symbol_grounds_or_is_refused(symbol: str | None) -> None:
    if symbol is not None:
        try:
            parse_symbol(symbol)
        except SymbolError as error:
            assert repr(symbol) in str(error)


@given(NAMES)
def test_any_aha_name_parses_or_says_why_not(name: str) -> None:
    parsed = parse_aha_name(name)
    if parsed is None:
        assert aha_name_problem(name)
    else:
        task, symbol, episode = parsed
        assert task and episode.isdigit()
        _symbol_grounds_or_is_refused(symbol)


def _frame(folder: Path, name: str) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    write_png(folder / name, np.zeros((4, 4, 3), np.uint8))


def _read_or_skipped(folder: Path, found: list[Trajectory], skipped: list[Skipped]) -> None:
    """`folder` is read as exactly one episode, or listed as skipped once, with a reason; not both. A hidden
    folder (a name starting with a dot: `.git`, `.cache`) is no episode and is left out of every layout by
    design (`data/folders.py`): neither read nor listed."""
    read = [trajectory for trajectory in found if trajectory.source == folder]
    passed = [item for item in skipped if item.path == folder]
    assert len(read) + len(passed) == (0 if folder.name.startswith(".") else 1), (folder.name, read, passed)
    assert all(item.reason for item in passed)
    for trajectory in read:
        _symbol_grounds_or_is_refused(trajectory.symbol)


AHA_EPISODE = "pick_cube_success_episode0"


@given(NAMES, st.booleans())
@example("pick_cube_grasp_wp2_episode3", True)  # read: both branches are met whatever is drawn
@example("pick_cube_grasp_wp2_episode3", False)
@example("notes", True)
@example("notes", False)
@example(".0", False)  # hidden: left out
def test_an_aha_folder_of_any_name_is_read_or_skipped(name: str, beside_an_episode: bool) -> None:
    assume(name != AHA_EPISODE)
    with tempfile.TemporaryDirectory() as root:
        _frame(Path(root) / name, "front_0.png")
        _frame(Path(root) / name, "front_1.png")
        if beside_an_episode:  # the layout is found by another folder: this one is judged among episodes
            _frame(Path(root) / AHA_EPISODE, "front_0.png")
        found, skipped = aha_trajectories(Path(root))
        _read_or_skipped(Path(root) / name, found, skipped)
        assert all(item.reason for item in skipped)


@given(NAMES)
@example("3_grasp_wp1")
@example(MANISKILL_SUCCESS)
@example("notes")
def test_a_maniskill_folder_of_any_name_is_read_or_skipped(name: str) -> None:
    with tempfile.TemporaryDirectory() as root:
        episode = Path(root) / "PickCube-v1" / "seed0" / name
        _frame(episode / "front", "0.png")
        _frame(episode / "front", "1.png")
        success = Path(root) / "PickCube-v1" / "seed1" / MANISKILL_SUCCESS  # the layout is found by it
        _frame(success / "front", "0.png")
        found, skipped = maniskill_trajectories(Path(root))
        assert all(trajectory.task == "PickCube-v1" for trajectory in found)
        _read_or_skipped(episode, found, skipped)
        assert all(item.reason for item in skipped)
