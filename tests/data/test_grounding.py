"""Grounding G must reproduce paper Table 5 exactly and reject unknown tokens."""

from __future__ import annotations

import pytest

import robofailring
from robofailring.data.grounding import failure_type, parse_symbol
from robofailring.errors import SymbolError

PREFIX = "The failure was caused by "


def test_paper_example() -> None:
    assert robofailring.ground("rotation_x_wp1") == (
        "The failure was caused by incorrect gripper rotation along the X-axis at the initial stage (Waypoint 1)"
    )


@pytest.mark.parametrize(
    ("token", "sentence"),
    [
        ("rotation_y", "incorrect gripper rotation along the Y-axis"),
        ("no_rotation", "gripper translates to the correct pose but fails to rotate"),
        ("translation_z", "positional deviation of the end-effector along the Z-axis"),
        ("slip", "object slippage from the gripper"),
        ("grasp", "gripper reaches target pose but fails to close"),
        ("wrong_sequence", "robot executes actions in an incorrect order"),
        ("wrong_object", "robot operates on an unintended object"),
    ],
)
def test_error_type_rows(token: str, sentence: str) -> None:
    assert robofailring.ground(token) == PREFIX + sentence


@pytest.mark.parametrize(
    ("stage", "words"),
    [
        (1, "initial stage (Waypoint 1)"),
        (2, "interaction / grasping stage (Waypoint 2)"),
        (3, "manipulation / movement stage (Waypoint 3)"),
        (4, "near-goal placement stage (Waypoint 4)"),
        (5, "final completion / retraction stage (Waypoint 5)"),
    ],
)
def test_stage_rows(stage: int, words: str) -> None:
    assert (
        robofailring.ground(f"slip_wp{stage}") == f"{PREFIX}object slippage from the gripper at the {words}"
    )


def test_episode_token_is_ignored() -> None:
    assert robofailring.ground("rotation_x_wp1_episode12") == robofailring.ground("rotation_x_wp1")


@pytest.mark.parametrize(
    ("maniskill", "failgen"),
    [("trans_x_stage2", "translation_x_wp2"), ("rot_y_1", "rotation_y_wp1"), ("grasp_stage3", "grasp_wp3")],
)
def test_maniskill_names_ground_like_failgen(maniskill: str, failgen: str) -> None:
    assert robofailring.ground(maniskill) == robofailring.ground(failgen)
    assert parse_symbol(maniskill).canonical == failgen


@pytest.mark.parametrize(
    ("symbol", "named"),
    [
        ("twist_x_wp1", "'twist'"),
        ("rotation_q_wp1", "'q'"),
        ("slip_wpx", "'wpx'"),
        ("wrong_thing_wp1", "'wrong'"),
        ("grasp_x_wp1", "'x'"),
    ],
)
def test_unknown_tokens_are_named(symbol: str, named: str) -> None:
    with pytest.raises(SymbolError) as error:
        robofailring.ground(symbol)
    assert named in str(error.value)
    assert symbol in str(error.value)


def test_failure_type() -> None:
    assert failure_type("translation_x_wp3") == "translation"
    assert failure_type("trans_y_stage1") == "translation"
    assert failure_type(None) == "success"


def test_maniskill_stages_outside_table_5_still_ground() -> None:
    assert robofailring.ground("trans_y_stage0") == (
        "The failure was caused by positional deviation of the end-effector along the Y-axis at stage 0 of the task"
    )
    assert parse_symbol("rot_z_7").canonical == "rotation_z_stage7"
    with pytest.raises(SymbolError, match="'lift'"):
        robofailring.ground("grasp_lift")


@pytest.mark.parametrize(
    ("symbol", "ending"),
    [
        ("wrong_sequence_wp0", "robot executes actions in an incorrect order at waypoint 0"),
        ("slip_wp9", "object slippage from the gripper at waypoint 9"),
        (
            "wrong_object_wp4",
            "robot operates on an unintended object at the near-goal placement stage (Waypoint 4)",
        ),
        ("wrong_object_wp0", "robot operates on an unintended object at waypoint 0"),
        ("wrong_object", "robot operates on an unintended object"),
    ],
)
def test_any_waypoint_grounds(symbol: str, ending: str) -> None:
    assert robofailring.ground(symbol) == PREFIX + ending
    assert parse_symbol(symbol).canonical == symbol
