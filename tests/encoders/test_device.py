"""`--device` checked once for every encoder kind and runtime (issue 50): a name that is no device is one
error before anything is read (the verbs: tests/cli/test_device_option.py); `cuda` where torch has no GPU
in tests/encoders/test_timm_encoder.py (torch: the slow lane)."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from robofailring.encoders import load_encoder
from robofailring.encoders.device import check_device_name
from robofailring.encoders.placement import EncoderPlacement
from robofailring.errors import SettingError


@pytest.mark.parametrize("device", ["npu", "bogus:7", "cuda:", "cuda:x", "CPU", "cpu:0", ""])
def test_a_name_that_is_no_device_is_refused_for_every_kind(device: str) -> None:
    with pytest.raises(
        SettingError, match=r"--device .* is not a device robofailring runs on: use cpu, cuda"
    ):
        load_encoder("pixels", device=device)
    with pytest.raises(SettingError, match="is not a device"):
        EncoderPlacement(device=device)


@pytest.mark.parametrize("device", [None, "cpu", "cuda", "cuda:0", "cuda:12", "mps"])
def test_every_device_form_is_taken(device: str | None) -> None:
    assert check_device_name(device) == device
    assert EncoderPlacement(device=device).device == device


@given(st.text(max_size=12))
def test_any_device_text_is_a_device_or_one_setting_error(text: str) -> None:
    try:
        assert check_device_name(text) == text
    except SettingError as error:
        assert repr(text) in str(error)
