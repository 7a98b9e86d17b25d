"""Neuro-symbolic grounding G (paper Appendix C, Table 5): failure symbol -> sentence.

Table 5 is extended, for one dataset or memory, by a `Vocabulary` of its own symbols and stage
words (read by `robofailring.data.vocabulary`); every function here takes it explicitly (None:
Table 5 alone), so a memory grounds with its own vocabulary and nothing is global.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Final

from robofailring.errors import SymbolError

#: (a) Error-type grounding, Table 5. ManiSkill-failgen spells translation/rotation `trans`/`rot`.
ERROR_TYPES: Final[dict[str, str]] = {
    "rotation": "incorrect gripper rotation",
    "no_rotation": "gripper translates to the correct pose but fails to rotate",
    "translation": "positional deviation of the end-effector",
    "slip": "object slippage from the gripper",
    "grasp": "gripper reaches target pose but fails to close",
    "wrong_sequence": "robot executes actions in an incorrect order",
    "wrong_object": "robot operates on an unintended object",
}
ERROR_ALIASES: Final[dict[str, str]] = {
    "trans": "translation",
    "rot": "rotation",
    "no_grasp": "grasp",
}
#: Error types that take an axis token.
AXIAL_TYPES: Final[frozenset[str]] = frozenset({"rotation", "translation"})
#: (b) Axis grounding.
AXES: Final[dict[str, str]] = {"x": "along the X-axis", "y": "along the Y-axis", "z": "along the Z-axis"}
#: (c) Execution-stage grounding.
STAGES: Final[dict[int, str]] = {
    1: "initial stage (Waypoint 1)",
    2: "interaction / grasping stage (Waypoint 2)",
    3: "manipulation / movement stage (Waypoint 3)",
    4: "near-goal placement stage (Waypoint 4)",
    5: "final completion / retraction stage (Waypoint 5)",
}

#: The symbol of a failure whose type was not labelled (a labels row with outcome `failure` and no symbol).
UNTYPED: Final[str] = "failure"
UNTYPED_SENTENCE: Final[str] = "A failure (type not labelled)"


@dataclass(frozen=True)
class Vocabulary:
    """A dataset's own failure symbols (symbol -> the words for its cause) and stage words, beyond Table 5.

    A symbol's words complete "The failure was caused by …", as Table 5's do; `stages` words
    replace Table 5's for those stage numbers (`wp<N>`, `stage<N>` or `<N>` in a symbol).
    """

    symbols: Mapping[str, str]
    stages: Mapping[int, str] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The vocabulary as its JSON file holds it (stage numbers as strings)."""
        written: dict[str, Any] = {"symbols": dict(self.symbols)}
        if self.stages:
            written["stages"] = {str(stage): words for stage, words in sorted(self.stages.items())}
        return written


_STAGE_TOKEN = re.compile(r"^(wp|stage|s)?(\d+)$")
_EPISODE_TOKEN = re.compile(r"^episode\d*$")
_MAX_STAGE_DIGITS: Final[int] = 9  # int() refuses thousands of digits; no task has a billion stages


@dataclass(frozen=True)
class ParsedSymbol:
    """A failure symbol split into its Table 5 parts."""

    error_type: str
    axis: str | None
    stage: int | None
    waypoint: bool = True  # the stage was written `wp<N>` (else ManiSkill's `stage<N>` or `<N>`)

    @property
    def canonical(self) -> str:
        """The symbol in FailGen spelling, e.g. ``translation_x_wp2``."""
        parts = [self.error_type]
        if self.axis:
            parts.append(self.axis)
        if self.stage is not None:
            named_wp = self.stage in STAGES or self.waypoint
            parts.append(f"wp{self.stage}" if named_wp else f"stage{self.stage}")
        return "_".join(parts)


def reserved_symbols() -> frozenset[str]:
    """The symbols Table 5 (and the untyped failure) already mean: a vocabulary may not redefine them."""
    return frozenset({*ERROR_TYPES, *ERROR_ALIASES, UNTYPED})


def _vocabulary(vocabulary: Vocabulary | None) -> str:
    errors = sorted([*ERROR_TYPES, *ERROR_ALIASES, UNTYPED])
    own = (
        f", this dataset's own symbols {sorted(vocabulary.symbols)}"
        if vocabulary is not None
        else " (a dataset's own symbols: pass --vocabulary FILE)"
    )
    return (
        f"error types {errors}{own}, axes {sorted(AXES)} (after rotation/translation), "
        f"stages wp<N> (Table 5 names wp1..wp5; also ManiSkill's stage<N> or <N>), and an ignored episode<N>"
    )


def parse_symbol(symbol: str, vocabulary: Vocabulary | None = None) -> ParsedSymbol:
    """Split a FailGen, ManiSkill-failgen or `vocabulary` symbol; raise SymbolError naming any unknown token."""
    tokens = [token for token in symbol.strip().lower().split("_") if token]
    if not tokens:
        raise SymbolError(f"empty failure symbol {symbol!r}; the vocabulary is {_vocabulary(vocabulary)}")
    while tokens and _EPISODE_TOKEN.match(tokens[0]):
        tokens.pop(0)
    if not tokens:
        raise SymbolError(
            f"failure symbol {symbol!r} names only an episode, no failure; "
            f"the vocabulary is {_vocabulary(vocabulary)}"
        )
    own = vocabulary.symbols if vocabulary is not None else {}
    error_type: str | None = None
    # The longest known head (`no_rotation` before `rotation`, a vocabulary's `slip_twice` before `slip`),
    # matched before episode tokens are dropped: a vocabulary's symbol may hold one (`slip_episode`).
    for width in range(len(tokens), 0, -1):
        head = "_".join(tokens[:width])
        if head in ERROR_TYPES or head in ERROR_ALIASES or head in own or head == UNTYPED:
            error_type = ERROR_ALIASES.get(head, head)
            tokens = [token for token in tokens[width:] if not _EPISODE_TOKEN.match(token)]
            break
    if error_type is None:
        raise SymbolError(
            f"unknown failure token {tokens[0]!r} in symbol {symbol!r}; "
            f"the vocabulary is {_vocabulary(vocabulary)}"
        )
    axis: str | None = None
    if tokens and tokens[0] in AXES:
        if error_type not in AXIAL_TYPES:
            raise SymbolError(f"axis token {tokens[0]!r} in symbol {symbol!r}: {error_type} takes no axis")
        axis = tokens.pop(0)
    stage: int | None = None
    waypoint = True
    if tokens:
        match = _STAGE_TOKEN.match(tokens[0])
        # Any waypoint index grounds (real exports use wp0 and wp6+); Table 5 names wp1..wp5.
        if match is None:
            raise SymbolError(
                f"unknown stage token {tokens[0]!r} in symbol {symbol!r}; "
                f"the vocabulary is {_vocabulary(vocabulary)}"
            )
        if len(match.group(2)) > _MAX_STAGE_DIGITS:
            raise SymbolError(f"stage token {tokens[0]!r} in symbol {symbol!r} is not a waypoint number")
        stage = int(match.group(2))
        waypoint = match.group(1) == "wp"
        tokens.pop(0)
    if tokens:
        raise SymbolError(
            f"unexpected token {tokens[0]!r} in symbol {symbol!r}; the vocabulary is {_vocabulary(vocabulary)}"
        )
    return ParsedSymbol(error_type=error_type, axis=axis, stage=stage, waypoint=waypoint)


def ground(symbol: str, vocabulary: Vocabulary | None = None) -> str:
    """G(y_sym): the deterministic sentence for a failure symbol (Table 5, extended by `vocabulary`).

    >>> ground("rotation_x_wp1")
    'The failure was caused by incorrect gripper rotation along the X-axis at the initial stage (Waypoint 1)'
    """
    parsed = parse_symbol(symbol, vocabulary)
    own = vocabulary if vocabulary is not None else Vocabulary(symbols={})
    if parsed.error_type == UNTYPED:
        sentence = UNTYPED_SENTENCE
    else:
        words = own.symbols.get(parsed.error_type) or ERROR_TYPES[parsed.error_type]
        sentence = f"The failure was caused by {words}"
    if parsed.axis:
        sentence += f" {AXES[parsed.axis]}"
    stages = {**STAGES, **own.stages}
    if parsed.stage in stages:
        sentence += f" at the {stages[parsed.stage]}"
    elif parsed.stage is not None and parsed.waypoint:
        sentence += f" at waypoint {parsed.stage}"
    elif parsed.stage is not None:
        sentence += f" at stage {parsed.stage} of the task"
    return sentence


def failure_type(symbol: str | None, vocabulary: Vocabulary | None = None) -> str:
    """The error type of a symbol (``rotation``, ``grasp``, a vocabulary's own, …); ``success`` for None."""
    return "success" if symbol is None else parse_symbol(symbol, vocabulary).error_type
