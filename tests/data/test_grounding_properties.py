"""Failure symbols are user input (labels files, folder names, memories): any string grounds or raises SymbolError."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from robofailring.data.grounding import AXES, ERROR_ALIASES, ERROR_TYPES, ground, parse_symbol
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
