"""Every job config is a composition of the values, never a copy of their fields (issue 47 item 1, issue 53), and each
verb's config and its run live in the verb's job module (issue 53 item 5).

What to read is a `DataSelection`, how a memory is made a `MemoryRecipe`, where an encoder runs an
`EncoderPlacement`, how runs are scored a `Scoring`, what opens a detector and decides a `DetectorConfig` (made of
the two), how thresholds are set a `ThresholdPolicy` (and, for replay and compare, which trajectories they
record, `Recordings`): each is checked once, where it is made, and a job holds it whole. A job holds only the
values that apply to it, so none refuses a setting of a value it holds.

A verb's job module (docs/architecture.md, "The one command line"): in the library, `robofailring/jobs/<verb>.py` for a verb that joins packages, or
`robofailring/<package>/job.py` for a verb that is one package's work (its modules take values it hands them, and
nothing below `jobs` may import `jobs`); in rfr_viz, `rfr_viz/jobs/<verb>.py`, which holds a config only the
recordings need and runs the verb, recording what the library's job gives, and hands a library config only to
the functions of its job module. A package's `job.py` is the top of its package: no other module of it imports
the job, so none takes its config. The verb -> config -> run map is read from the command itself (each verb's
body: the config class it builds and the job function it hands it to), so a new verb is checked without a line
here.
"""

from __future__ import annotations

import ast
import dataclasses
import importlib
import inspect
import sys
import textwrap
import typing
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from rfr_viz.jobs.compare import CompareConfig
from rfr_viz.jobs.demo import DemoConfig
from rfr_viz.jobs.recorded import Recordings
from rfr_viz.jobs.replay import ReplayConfig
from rfr_viz.jobs.review import ReviewConfig
from rfr_viz.jobs.watch import WatchConfig
from robofailring.calibration.job import CalibrateConfig
from robofailring.calibration.policy import ThresholdPolicy
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DetectorConfig, Scoring
from robofailring.encoders.placement import EncoderPlacement
from robofailring.encoders.training import TrainEncoderConfig
from robofailring.errors import SettingError
from robofailring.evaluation.job import EvaluateConfig
from robofailring.explain.vlm import VLMConfig
from robofailring.jobs.build_memory import BuildMemoryConfig
from robofailring.jobs.compare_encoders import CompareEncodersConfig
from robofailring.jobs.detect import DetectConfig
from robofailring.memory.recipe import MemoryRecipe
from robofailring.sim import GenerateConfig
from robofailring.triage import TriageConfig

# verbs that build no job config: a memory's summary, a recording opened or shared, a report explained
CONFIGLESS = {"memory-info", "open", "share", "explain"}


@dataclass(frozen=True)
class VerbJob:
    verb: str
    config: type  # the config class the verb builds and hands to its run
    run: Callable[..., Any]  # the job function it calls with it


def verb_functions() -> dict[str, Callable[..., Any]]:
    """Every verb of the `robofailring` command and the function typer calls for it (before `takes`)."""
    from rfr_viz.cli.app import app

    return {
        command.name: inspect.unwrap(command.callback)
        for group in app.registered_groups
        if group.typer_instance is not None
        for command in group.typer_instance.registered_commands
        if command.name is not None and command.callback is not None
    }


def _imported_in(body: ast.FunctionDef) -> dict[str, Any]:
    """The names the verb imports inside its body (the CLI imports its job there), resolved."""
    names: dict[str, Any] = {}
    for node in ast.walk(body):
        if isinstance(node, ast.ImportFrom) and node.module is not None:
            module = importlib.import_module(node.module)
            for alias in node.names:
                names[alias.asname or alias.name] = getattr(module, alias.name)
    return names


def job_of(verb: str, function: Callable[..., Any]) -> VerbJob | None:
    """The config class `verb` builds and the job function it hands it to (None: it builds none)."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(function)))
    body = next(node for node in ast.walk(tree) if isinstance(node, ast.FunctionDef))
    imported = _imported_in(body)

    def config_built(node: ast.expr) -> type | None:
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
            made = imported.get(node.func.id)
            return made if isinstance(made, type) and dataclasses.is_dataclass(made) else None
        return None

    variables = {  # `config = SomeConfig(...)`
        target.id: made
        for node in ast.walk(body)
        if isinstance(node, ast.Assign) and (made := config_built(node.value)) is not None
        for target in node.targets
        if isinstance(target, ast.Name)
    }
    for node in ast.walk(body):
        if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.args):
            continue
        run = imported.get(node.func.id)
        if not inspect.isfunction(run):
            continue
        first = node.args[0]
        config = variables.get(first.id) if isinstance(first, ast.Name) else config_built(first)
        if config is not None:
            return VerbJob(verb, config, run)
    return None


def job_modules(verb: str) -> set[str]:
    """The modules the convention allows to hold `verb`'s config."""
    name = verb.replace("-", "_")
    return {f"robofailring.jobs.{name}", f"rfr_viz.jobs.{name}"}


def _is_package_job(module: str) -> bool:
    parts = module.split(".")
    return len(parts) == 3 and parts[0] == "robofailring" and parts[2] == "job"


VERBS = verb_functions()
VERB_JOBS = {verb: job_of(verb, function) for verb, function in VERBS.items()}


VALUES = (DataSelection, MemoryRecipe, EncoderPlacement, Scoring, DetectorConfig, ThresholdPolicy)
HELD = (*VALUES, Recordings)  # Recordings: replay's and compare's (a watch, a review record otherwise)
HELD_JOBS = (TrainEncoderConfig,)  # the training TrainEncoderJob holds whole, beside the simulation
# generate reads no data, judges nothing and sets no threshold: it writes a dataset from the simulator's settings
NO_VALUE = {GenerateConfig}
EXPLICIT = (
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
    TrainEncoderConfig,  # held whole by train-encoder's TrainEncoderJob
)
JOB_CONFIGS = tuple(
    dict.fromkeys([*EXPLICIT, *(job.config for job in VERB_JOBS.values() if job is not None)])
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
    values = values or (*HELD, *HELD_JOBS)
    return any(value in (annotation, *typing.get_args(annotation)) for value in values) or any(
        _holds_a_value(arg, *values) for arg in typing.get_args(annotation)
    )


@pytest.mark.parametrize("job", JOB_CONFIGS, ids=lambda job: job.__name__)
def test_no_job_config_repeats_a_field_of_a_value(job: type) -> None:
    """Not one field of a value in a job config beside the value."""
    value_fields = {field.name for value in VALUES for field in dataclasses.fields(value)}
    hints = typing.get_type_hints(job, localns={"VLMConfig": VLMConfig})
    own = {field.name for field in dataclasses.fields(job) if not _holds_a_value(hints[field.name])}
    assert own & value_fields == OWN.get(job, set())
    assert any(_holds_a_value(hints[field.name]) for field in dataclasses.fields(job)) != (job in NO_VALUE)


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


def _folds() -> typing.Any:
    from robofailring.evaluation.folds import FoldPlan

    return FoldPlan.parse("loo")


def test_the_verbs_are_read_from_the_command() -> None:
    import typer

    from rfr_viz.cli.app import app

    assert set(VERBS) == set(typer.main.get_command(app).commands)  # type: ignore[attr-defined]
    assert {verb for verb, job in VERB_JOBS.items() if job is None} == CONFIGLESS
    found = {
        verb: (job.config.__name__, job.run.__name__) for verb, job in VERB_JOBS.items() if job is not None
    }
    assert found["generate"] == ("GenerateConfig", "simulate")
    assert found["train-encoder"] == ("TrainEncoderJob", "run_train_encoder")
    assert found["compare"] == ("CompareConfig", "compare")


@pytest.mark.parametrize("verb", sorted(v for v, job in VERB_JOBS.items() if job is not None))
def test_a_verbs_config_lives_in_its_job_module(verb: str) -> None:
    """`<verb>`'s config in `jobs/<verb>.py` (library or rfr_viz) or its package's `job.py`; its run beside it,
    or in `rfr_viz/jobs/<verb>.py` where the verb records (over the library functions beside the config: the
    next test)."""
    job = VERB_JOBS[verb]
    assert job is not None
    home = job.config.__module__
    assert home in job_modules(verb) or _is_package_job(home), (
        f"{verb}: {job.config.__name__} lives in {home}, not in its job module"
    )
    assert job.run.__module__ in {home, f"rfr_viz.jobs.{verb.replace('-', '_')}"}, (
        f"{verb}: its run {job.run.__name__} lives in {job.run.__module__}, away from its config in {home}"
    )


def handed_the_config(job: VerbJob) -> dict[str, Callable[..., Any]]:
    """The functions of other modules that `job`'s run module (`rfr_viz/jobs/<verb>.py`) hands the verb's config
    to: in any of its functions, a call with a parameter annotated with the config's class among its arguments."""
    module = sys.modules[job.run.__module__]
    tree = ast.parse(inspect.getsource(module))
    handed: dict[str, Callable[..., Any]] = {}
    for function in (node for node in ast.walk(tree) if isinstance(node, ast.FunctionDef)):
        arguments = function.args
        holding = {
            argument.arg
            for argument in [*arguments.posonlyargs, *arguments.args, *arguments.kwonlyargs]
            if isinstance(argument.annotation, ast.Name | ast.Constant)
            and ast.unparse(argument.annotation).strip("'\"") == job.config.__name__
        }
        for call in (node for node in ast.walk(function) if isinstance(node, ast.Call)):
            passed = [*call.args, *(keyword.value for keyword in call.keywords)]
            if not isinstance(call.func, ast.Name) or not any(
                isinstance(value, ast.Name) and value.id in holding for value in passed
            ):
                continue
            called = getattr(module, call.func.id, None)
            if inspect.isfunction(called) and called.__module__ != module.__name__:
                handed[call.func.id] = called
    return handed


RECORDING_RUNS = sorted(
    verb
    for verb, job in VERB_JOBS.items()
    if job is not None
    and job.run.__module__ == f"rfr_viz.jobs.{verb.replace('-', '_')}"
    and job.config.__module__.startswith("robofailring.")
)


@pytest.mark.parametrize("verb", RECORDING_RUNS)
def test_a_recording_verb_hands_its_config_only_to_its_job_module(verb: str) -> None:
    """Where `rfr_viz/jobs/<verb>.py` runs a verb whose config is the library's, every function of another
    module it hands the config to lives beside the config: the library's run of the verb is in its job module
    too (evaluate's `run_evaluation`, `growth_curve`, `cross_validate_alone` in `evaluation/job.py`)."""
    job = VERB_JOBS[verb]
    assert job is not None
    handed = handed_the_config(job)
    assert handed, f"{verb}: {job.run.__name__} hands {job.config.__name__} to no library function"
    away = {name: function.__module__ for name, function in handed.items()}
    assert {name: home for name, home in away.items() if home != job.config.__module__} == {}, (
        f"{verb}: its config lives in {job.config.__module__}"
    )


def test_the_recording_verbs_over_a_library_job_are_found() -> None:
    assert RECORDING_RUNS == ["compare-encoders", "evaluate", "triage"]
    evaluate = VERB_JOBS["evaluate"]
    assert evaluate is not None
    assert set(handed_the_config(evaluate)) == {
        "check_growth",
        "run_evaluation",
        "cross_validate_alone",
        "growth_curve",
    }


LIBRARY = Path(__file__).resolve().parents[2] / "src" / "robofailring"
PACKAGE_JOBS = sorted(path.parent.name for path in LIBRARY.glob("*/job.py"))


def _imports(path: Path) -> set[str]:
    """The modules `path` (a module of the library) imports, anywhere in it (inside functions and
    `if TYPE_CHECKING:` too); `from robofailring.<package> import name` is the package itself unless `name` is
    one of its modules."""
    parts = ["robofailring", *path.relative_to(LIBRARY).with_suffix("").parts]
    imported: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            imported.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = (
                ".".join([*parts[: -node.level], *filter(None, [node.module])]) if node.level else node.module
            )
            assert base is not None
            for alias in node.names:
                inside = LIBRARY.joinpath(*base.split(".")[1:], alias.name)
                below = inside.with_suffix(".py").exists() or (inside / "__init__.py").exists()
                imported.add(f"{base}.{alias.name}" if below else base)
    return imported


@pytest.mark.parametrize("package", PACKAGE_JOBS)
def test_a_package_job_module_is_the_top_of_its_package(package: str) -> None:
    """No module of `robofailring.<package>` imports its `job.py` (or the package, whose `__init__` may re-export
    the job) but that `__init__`: the package's modules take values, never the job's config, and no import
    circle holds the job's run away from its config (issue 53)."""
    job, itself = f"robofailring.{package}.job", f"robofailring.{package}"
    importing = sorted(
        str(path.relative_to(LIBRARY))
        for path in (LIBRARY / package).rglob("*.py")
        if path.name != "job.py"
        and path != LIBRARY / package / "__init__.py"
        and _imports(path) & {job, itself}
    )
    assert importing == []


def test_every_package_job_module_is_checked() -> None:
    assert PACKAGE_JOBS == ["calibration", "evaluation", "sim", "triage"]


def test_a_package_job_module_is_one_verbs() -> None:
    """A package's `job.py` is the job of one verb: two verbs of one package go to `jobs/<verb>.py`."""
    homes: dict[str, list[str]] = {}
    for verb, job in VERB_JOBS.items():
        if job is not None and _is_package_job(job.config.__module__):
            homes.setdefault(job.config.__module__, []).append(verb)
    assert homes and all(len(verbs) == 1 for verbs in homes.values()), homes


@pytest.mark.parametrize("job", JOB_CONFIGS, ids=lambda job: job.__name__)
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
    sources = [Path(module.__file__).read_text(encoding="utf-8") for module in map(_module, JOB_CONFIGS)]
    for said in (
        "give no memory, encoder, rule or threshold",
        "give its detector no rule or threshold",
        "give no rule, threshold or encoder to its detector",
    ):
        assert not any(said in source for source in sources)


def _module(job: type) -> typing.Any:
    return sys.modules[job.__module__]
