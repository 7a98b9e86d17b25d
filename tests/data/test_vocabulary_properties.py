"""A vocabulary file is user input: any YAML or JSON text is a Vocabulary or one VocabularyError naming the
file, never a TypeError, a RecursionError or an alias expanded without bound (issue 35, item 6)."""

from __future__ import annotations

import json
from pathlib import Path

import yaml
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from robofailring.data.grounding import Vocabulary
from robofailring.data.vocabulary import read_vocabulary
from robofailring.errors import VocabularyError

SCALARS = st.one_of(
    st.sampled_from(["knocked_cup", "Drawer_Timeout", "grasp_wp2", "the cup fell", "", " ", "2", "~"]),
    st.integers(-3, 3),
    st.none(),
    st.booleans(),
)
VALUES = st.recursive(
    SCALARS,
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(SCALARS, inner, max_size=3),
    max_leaves=8,
)
YAML_CHARACTERS = st.text(alphabet="symbols: stages&*[]{}?-,'\"!\n\t knocked_cup 12#|>.", max_size=120)


def shared(value: object) -> object:
    """A document that uses one object twice: yaml.dump writes it once with an anchor, then an alias."""
    return {"symbols": {"knocked_cup": value, "slipped_cup": value}}


def check(path: Path) -> None:
    try:
        vocabulary = read_vocabulary(path)
    except VocabularyError as error:
        assert str(path) in str(error)
    else:
        assert isinstance(vocabulary, Vocabulary) and vocabulary.symbols


@settings(suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    st.one_of(
        VALUES.map(lambda value: yaml.safe_dump({"symbols": value})),
        st.lists(VALUES, min_size=1, max_size=3).map(lambda value: yaml.safe_dump(shared(value))),
        YAML_CHARACTERS,
        st.integers(1, 3000).map(lambda depth: "symbols: " + "[" * depth + "]" * depth),
    )
)
@example("symbols:\n  [a, b]: words\n")
@example("symbols:\n  a: &a [x, x]\n  b: [*a, *a]\n")
@example("? {a: 1}\n: x\n")
def test_any_yaml_is_a_vocabulary_or_one_vocabulary_error(tmp_path: Path, text: str) -> None:
    path = tmp_path / "words.yaml"
    path.write_text(text, encoding="utf-8")
    check(path)


@settings(suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.one_of(VALUES.map(lambda value: json.dumps({"symbols": value})), st.text(max_size=60)))
@example('{"symbols": ' + "[" * 100_000 + "]" * 100_000 + "}")
def test_any_json_is_a_vocabulary_or_one_vocabulary_error(tmp_path: Path, text: str) -> None:
    path = tmp_path / "words.json"
    path.write_text(text, encoding="utf-8")
    check(path)
