"""The CLI's numeric options are user input: any text for --delta, --gamma, --k, --stride, --target-fpr,
--fps or --speed is used or refused with exit status 2 and a message, never a traceback; the checks behind them
return the value or raise SettingError."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fault_helpers import cli
from hypothesis import example, given
from hypothesis import strategies as st

from rfr_viz.jobs.recorded import check_fps
from rfr_viz.jobs.replay import check_speed
from robofailring.calibration.conformal import check_target_fpr
from robofailring.detection.config import check_k, check_stride
from robofailring.detection.rules import RULES
from robofailring.errors import SettingError
from robofailring.memory.thinning import check_step

TEXT = st.one_of(
    st.sampled_from(
        ["nan", "-nan", "inf", "-inf", "1e309", "-0", "0", "1", "0.5", "-1", "", " ", "1_0", "0x10"]
    ),
    st.integers(-(10**30), 10**30).map(str),
    st.floats().map(str),
    st.text(max_size=8),
).filter(lambda text: "\0" not in text)

OPTIONS = {
    "detect": ("--delta", "--gamma", "--k", "--stride"),
    "calibrate": ("--target-fpr", "--stride"),
    "replay": ("--fps", "--k", "--stride", "--delta"),
    "watch": ("--fps", "--speed"),
}


@pytest.fixture(scope="module")
def missing(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("numeric") / "nothing-here"


@given(st.sampled_from(sorted(OPTIONS)), st.data())
def test_any_numeric_option_text_is_refused_with_status_2_not_a_traceback(
    missing: Path, verb: str, data: st.DataObject
) -> None:
    option, value = data.draw(st.sampled_from(OPTIONS[verb])), data.draw(TEXT)
    extra = {"replay": ("--out", missing / "rec"), "watch": ("--save", missing / "w.rrd")}.get(verb, ())
    result = cli(verb, missing, "--memory", missing, *extra, option, value)
    assert result.exit_code == 2, result.output  # a bad value, or (for a good one) the missing memory
    assert isinstance(result.exception, SystemExit), repr(result.exception)
    assert "Traceback" not in result.output and "rror" in result.output


NUMBER = st.one_of(st.floats(), st.integers(-(10**6), 10**6))
CHECKS: dict[str, Callable[[Any], Any]] = {
    "k": check_k,
    "stride": check_stride,
    "target_fpr": check_target_fpr,
    **{rule.threshold_key: rule.check_threshold for rule in RULES.values()},
    "fps": check_fps,
    "speed": check_speed,
    "success_step": check_step,
}


@given(st.sampled_from(sorted(CHECKS)), NUMBER)
@example("k", math.nan)  # found by this test: check_k let NaN (and 2.5) through to Faiss
@example("stride", 2.5)
@example("stride", 10**20)  # issue 35: past int64, np.arange gave an object array (an IndexError later)
@example("k", 10**20)
@example("fps", 1e-300)  # issue 45, item 6: frame 1 at 1e300 s, an OverflowError in the recording
@example("fps", 1e-10)
@example("speed", math.nan)  # issue 45, item 6: watch played as fast as it could
def test_every_setting_check_returns_the_value_or_raises_a_setting_error(name: str, value: float) -> None:
    try:
        checked = CHECKS[name](value)
    except SettingError as error:
        assert str(value) in str(error)
    else:
        assert checked == value and not math.isnan(value)
        if name == "fps":  # a million frames' times still fit Rerun's int64 nanoseconds
            assert 10**6 / checked * 1e9 < 2**63
        if name == "speed":
            assert math.isfinite(checked) and checked >= 0
        if name in ("k", "stride"):
            assert isinstance(checked, int), f"{name} accepted the non-integer {value!r}"


@given(st.integers(-(10**30), 10**30))
@example(2**63 - 1)
@example(2**63)
def test_an_accepted_stride_numbers_frames_as_int64(stride: int) -> None:
    try:
        check_stride(stride)
    except SettingError as error:
        assert str(stride) in str(error)
    else:
        assert np.arange(0, 10, stride).dtype == np.int64
