"""Failure symbols are user input (labels files, folder names, memories): any string grounds or raises SymbolError."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from robofailring.data.grounding import AXES, ERROR_ALIASES, ERROR_TYPES, ground, parse_symbol
from robofailring.data.vocabulary import vocabulary_from
from robofailring.errors import SymbolError

# tokens near the vocabulary, so generated symbols reach every branch of the parser
TOKENS = st.one_of(
    st.sampled_from([*ERROR_TYPES, *ERROR_ALIASES, *AXES, "episode", "wp", "stage", "s", "x"]),
    st.from_regex(r"(wp|stage|s|episode)?[0-9]{1,12}", fullmatch=True),
    st.text(max_size=6),
)
# short mixes of the tokens the parser drops or reads last (episode<N>, stages), beside one error type
ENDINGS = st.lists(
    st.sampled_from(["episode", "Episode7", "episode12", "wp2", "stage3", "4", "grasp"]), max_size=3
)
SYMBOLS = st.one_of(st.text(), st.lists(TOKENS, max_size=5).map("_".join), ENDINGS.map("_".join))


@settings(max_examples=150)  # cheap (no I/O), and enough to reach rare token mixes every run
@given(SYMBOLS)
def test_any_symbol_grounds_or_raises_a_symbol_error_naming_it(symbol: str) -> None:
    try:
        sentence = ground(symbol)
    except SymbolError as error:
        assert repr(symbol) in str(error)
    else:
        assert sentence.startswith("The failure was caused by ")
        assert ground(parse_symbol(symbol).canonical) == sentence  # the canonical spelling means the same


# a vocabulary's own symbol that begins with a Table 5 word (`slip_twice`), read as read_vocabulary reads it
OWN_SYMBOLS = st.tuples(
    st.sampled_from(sorted([*ERROR_TYPES, *ERROR_ALIASES])),
    st.lists(
        st.one_of(
            st.from_regex(r"[a-z0-9]{1,8}", fullmatch=True),
            st.sampled_from(["twice", "x", "wp", "2", "wp3", "stage", "episode", "episode5", "failure"]),
        ),
        min_size=1,
        max_size=3,
    ),
).map(lambda parts: "_".join([parts[0], *parts[1]]))
STAGE_ENDINGS = st.sampled_from(["", "_wp2", "_stage7", "_3", "_wp2_episode4", "_episode12"])


@settings(max_examples=150)
@given(OWN_SYMBOLS, STAGE_ENDINGS)
def test_a_vocabulary_symbol_beginning_with_a_table_5_word_grounds_as_itself(own: str, ending: str) -> None:
    vocabulary = vocabulary_from({"symbols": {own: "the robot's own words"}}, where="the test")
    parsed = parse_symbol(own + ending, vocabulary)
    assert parsed.error_type == own
    sentence = ground(own + ending, vocabulary)
    assert sentence.startswith("The failure was caused by the robot's own words")
    assert ground(parsed.canonical, vocabulary) == sentence
