"""Encoder specs are user input (`--encoder`, a memory's manifest): any string parses or raises EncoderError."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from robofailring.encoders.spec import EncoderSpec
from robofailring.errors import EncoderError

SPECS = st.one_of(
    st.text(),
    st.lists(st.sampled_from(["pixels", "open_clip", "trained", "", " ", "ViT-B-32", "a:b"]), max_size=4).map(
        ":".join
    ),
    st.lists(
        st.sampled_from(
            ["pixels", "open_clip:a:b", "trained:d", "", "@", "onnx", "torch", "onnx-int8", "@onnx"]
        ),
        max_size=4,
    ).map("@".join),
)


@given(SPECS)
def test_any_spec_parses_or_raises_an_encoder_error_naming_it(text: str) -> None:
    try:
        spec = EncoderSpec.parse(text)
    except EncoderError as error:
        assert repr(text.strip()) in str(error)
    else:
        assert EncoderSpec.parse(str(spec)) == spec  # what a memory records reads back the same
