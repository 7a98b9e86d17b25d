"""Every job config is a composition of the values, never a copy of their fields (issue 47 item 1, issue 53).

What to read is a `DataSelection`, how a memory is made a `MemoryRecipe`, where an encoder runs an
`EncoderPlacement`, how runs are scored a `Scoring`, what opens a detector and decides a `DetectorConfig` (made of
the two), how thresholds are set a `ThresholdPolicy` (and, for replay and compare, which trajectories they
record, `Recordings`): each is checked once, where it is made, and a job holds it whole. A job holds only the
values that apply to it, so none refuses a setting of a value it holds.
"""

from __future__ import annotations

import dataclasses
import typing
from pathlib import Path

import pytest

from rfr_viz.jobs.demo import DemoConfig
from rfr_viz.jobs.recorded import Recordings
from rfr_viz.jobs.replay import CompareConfig, ReplayConfig
from rfr_viz.jobs.review import ReviewConfig
from rfr_viz.jobs.watch import WatchConfig
from robofailring.calibration.job import CalibrateConfig
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DetectorConfig, Scoring
from robofailring.encoders.placement import EncoderPlacement
from robofailring.encoders.training import TrainEncoderConfig
from robofailring.errors import SettingError
from robofailring.evaluation.comparison import CompareEncodersConfig
from robofailring.evaluation.training import EvaluateConfig
from robofailring.explain.vlm import VLMConfig
from robofailring.jobs.build_memory import BuildMemoryConfig
from robofailring.jobs.detect import DetectConfig
from robofailring.memory.recipe import MemoryRecipe
from robofailring.triage import TriageConfig

VALUES = (DataSelection, MemoryRecipe, EncoderPlacement, Scoring, DetectorConfig, ThresholdPolicy)
HELD = (*VALUES, Recordings)  # Recordings: replay's and compare's (a watch, a review record otherwise)
JOBS = (
    BuildMemoryConfig,
    DetectConfig,
    CalibrateConfig,
    EvaluateConfig,
    CompareEncodersConfig,
    TriageConfig,
    ReplayConfig,
    CompareConfig,
    ReviewConfig,
    WatchConfig,
    DemoConfig,
    TrainEncoderConfig,
)
# a training job has no detector: the device it trains on is its own setting, not an EncoderPlacement's; the
# jobs that set every rule's threshold name the memory they open (and calibration its encoder) beside its Scoring
# and EncoderPlacement: a DetectorConfig would carry a rule and thresholds they could only refuse
OWN: dict[type, set[str]] = {
    TrainEncoderConfig: {"device"},
    CalibrateConfig: {"memory", "encoder"},
    EvaluateConfig: {"memory"},
}


def _holds_a_value(annotation: object, *values: type) -> bool:
    values = values or HELD
    return any(value in (annotation, *typing.get_args(annotation)) for value in values) or any(
        _holds_a_value(arg, *values) for arg in typing.get_args(annotation)
    )


@pytest.mark.parametrize("job", JOBS, ids=lambda job: job.__name__)
def test_no_job_config_repeats_a_field_of_a_value(job: type) -> None:
    """Not one field of a value in a job config beside the value."""
    value_fields = {field.name for value in VALUES for field in dataclasses.fields(value)}
    hints = typing.get_type_hints(job, localns={"VLMConfig": VLMConfig})
    own = {field.name for field in dataclasses.fields(job) if not _holds_a_value(hints[field.name])}
    assert own & value_fields == OWN.get(job, set())
    assert any(_holds_a_value(hints[field.name]) for field in dataclasses.fields(job))


def test_each_value_is_checked_where_it_is_made(tmp_path: Path) -> None:
    """A bad setting is one SettingError at the value, before any job reads a file."""
    for make, message in (
        (lambda: DataSelection(tmp_path, views="a,,b"), "an empty view name"),
        (lambda: ThresholdPolicy(target_fpr=1.5), "target FPR must be in"),
        (lambda: ThresholdPolicy(band="wide"), "band"),
        (lambda: ThresholdPolicy(fusion="mean"), "fusion"),
        (lambda: Scoring(k=0), "k \\(neighbours per query\\)"),
        (lambda: Scoring(modality="sound"), "--modality must be one of"),
        (lambda: EncoderPlacement(device="npu"), "is not a device"),
        (lambda: DetectorConfig(rule="best"), "best"),
        (lambda: MemoryRecipe(pairing="sum"), "pairing"),
        (lambda: Recordings(fps=0.0), "--fps must be"),
    ):
        with pytest.raises(SettingError, match=message):
            make()


def test_another_dataset_is_read_as_this_one_with_its_own_labels(tmp_path: Path) -> None:
    data = DataSelection(tmp_path / "a", labels=tmp_path / "a.csv", task="pick", views="front")
    other = data.other(tmp_path / "b", labels=tmp_path / "b.csv")
    assert (other.root, other.labels, other.task, other.views) == (
        tmp_path / "b",
        tmp_path / "b.csv",
        "pick",
        "front",
    )
    assert data.other(tmp_path / "b").labels == tmp_path / "a.csv"  # none of its own: these


def test_a_recipe_knows_the_settings_chosen() -> None:
    """`build-memory --add-to` keeps the memory's own recipe but for the settings given."""
    chosen = MemoryRecipe.chosen("pixels", pairing="concat")
    assert chosen == MemoryRecipe(pairing="concat")  # the defaults for the rest
    assert chosen.was_given("pairing") and not chosen.was_given("failure_frames")
    assert MemoryRecipe().was_given("failure_frames")  # a recipe written out is chosen in full


def test_jobs_refuse_settings_their_values_cannot_take(tmp_path: Path) -> None:
    data = DataSelection(tmp_path)
    with pytest.raises(SettingError, match="leave out --memory and give a target FPR"):
        EvaluateConfig(data=data, out=tmp_path, threshold_policy=None, folds=_folds())


@pytest.mark.parametrize("job", JOBS, ids=lambda job: job.__name__)
def test_a_job_holds_only_the_values_that_apply(job: type) -> None:
    """A job that encodes but judges nothing holds an `EncoderPlacement`, one that sets thresholds a `Scoring`
    beside it, never a `DetectorConfig` whose rule or thresholds it would have to refuse."""
    hints = typing.get_type_hints(job, localns={"VLMConfig": VLMConfig})
    held = {
        value
        for field in dataclasses.fields(job)
        for value in VALUES
        if _holds_a_value(hints[field.name], value)
    }
    if ThresholdPolicy in held:  # it sets thresholds: no rule or threshold given to it
        assert DetectorConfig not in held, job
    if job in (BuildMemoryConfig, DemoConfig):
        assert held & {EncoderPlacement, Scoring, DetectorConfig} == {EncoderPlacement}


def test_no_job_refuses_a_detector_setting_at_run_time() -> None:
    """The three refusals of issue 53 (build-memory: a memory, encoder, rule or threshold; calibrate: a rule or
    threshold; evaluate: a rule, threshold or encoder) are gone with the fields: none of them can be given."""
    for job, refused in (
        (BuildMemoryConfig, {"detector", "memory", "encoder", "rule", "thresholds"}),
        (CalibrateConfig, {"detector", "rule", "thresholds"}),
        (EvaluateConfig, {"detector", "rule", "thresholds", "encoder"}),
    ):
        assert not {field.name for field in dataclasses.fields(job)} & refused, job
    sources = [Path(module.__file__).read_text(encoding="utf-8") for module in map(_module, JOBS)]
    for said in (
        "give no memory, encoder, rule or threshold",
        "give its detector no rule or threshold",
        "give no rule, threshold or encoder to its detector",
    ):
        assert not any(said in source for source in sources)


def _module(job: type) -> typing.Any:
    import sys

    return sys.modules[job.__module__]


def _folds() -> typing.Any:
    from robofailring.evaluation.training import FoldPlan

    return FoldPlan.parse("loo")
