"""Each value's options are declared once, as an option group, and no two verbs repeat an option list
(issue 47 item 2): a verb lists the groups it takes (`robofailring.cli.groups.takes`)."""

from __future__ import annotations

import dataclasses
import inspect
import itertools
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import pytest
import typer
from typer.testing import CliRunner

from rfr_viz.cli.app import app as robofailring_app
from rfr_viz.cli.jobs import app as jobs_app
from rfr_viz.cli.live import app as live_app
from rfr_viz.cli.options import recordings_options
from rfr_viz.cli.replay import app as replay_app
from rfr_viz.cli.triage import app as triage_app
from rfr_viz.jobs.recorded import Recordings
from robofailring.calibration.policy import DEFAULT_TARGET_FPR, ThresholdPolicy
from robofailring.cli.groups import Declared, OptionGroup, takes
from robofailring.cli.option_groups import (
    DETECTOR,
    SCORING,
    data_options,
    detector_options,
    placement_options,
    recipe_options,
    scoring_options,
    threshold_options,
    vlm_options,
)
from robofailring.cli.verbs import app as library_app
from robofailring.data.selection import DataSelection
from robofailring.detection.config import DEFAULT_DETECTOR, DetectorConfig, Scoring
from robofailring.encoders.placement import EncoderPlacement
from robofailring.memory.recipe import MemoryRecipe

GROUPS: dict[Callable[..., Any], tuple[type, dict[str, tuple[str, ...]]]] = {
    # the function that makes a value, the value, and which of its fields an option of another name makes
    data_options: (DataSelection, {"root": ("data",)}),
    recipe_options: (MemoryRecipe, {"given": ()}),  # which were given: the options say it by being given
    detector_options: (DetectorConfig, {"rule": ("score",), "thresholds": ("delta", "gamma", "eta")}),
    scoring_options: (Scoring, {}),
    placement_options: (EncoderPlacement, {}),
    threshold_options: (ThresholdPolicy, {}),
    recordings_options: (Recordings, {"trajectories": ("trajectory",)}),
}
#: Options a verb declares itself under a group's flag: lists, one per memory or encoder compared.
OWN_LISTS = {
    ("compare", "--memory"),
    ("compare", "--delta"),
    ("compare", "--data-root"),
    ("compare-encoders", "--encoder"),
}


def _verbs() -> dict[str, Any]:
    """Every verb's function as registered (the `takes` wrapper, whose `__wrapped__` is the verb's own)."""
    apps = (library_app, replay_app, jobs_app, triage_app, live_app)
    return {command.name: command.callback for app in apps for command in app.registered_commands}


def _flags(parameter: inspect.Parameter) -> tuple[str, ...]:
    """An option's flags (`--k`; typer's `--<name>` when it names none); () for an argument."""
    for info in getattr(parameter.annotation, "__metadata__", ()):
        if isinstance(info, typer.models.OptionInfo):
            named = tuple(str(flag) for flag in (info.default, *(info.param_decls or ())) if flag is not ...)
            return named or ("--" + parameter.name.replace("_", "-"),)
    return ()


def _own_options(verb: Any) -> dict[str, inspect.Parameter]:
    """The options a verb declares itself (its groups' not included), by parameter name."""
    own = inspect.signature(getattr(verb, "__wrapped__", verb), eval_str=True).parameters
    return {name: parameter for name, parameter in own.items() if _flags(parameter)}


def _group_flags() -> set[str]:
    return {
        flag
        for build in (
            data_options,
            recipe_options,
            detector_options,
            scoring_options,
            placement_options,
            threshold_options,
            vlm_options,
        )
        for parameter in inspect.signature(build, eval_str=True).parameters.values()
        for flag in _flags(parameter)
    }


def test_no_verb_declares_an_option_of_a_value_itself() -> None:
    """--k, --labels, --target-fpr…: only their group declares them; a verb takes the group."""
    groups = _group_flags()
    assert {"--memory", "--k", "--task", "--gamma", "--encoder", "--target-fpr", "--vlm-url"} <= groups
    declared = {
        (verb, flag)
        for verb, function in _verbs().items()
        for parameter in _own_options(function).values()
        for flag in _flags(parameter)
        if flag in groups
    }
    assert declared == OWN_LISTS


def _declaration(parameter: inspect.Parameter) -> tuple[tuple[str, ...], str | None]:
    """An option as its verb's help shows it: its flags and help text."""
    infos = [i for i in parameter.annotation.__metadata__ if isinstance(i, typer.models.OptionInfo)]
    return _flags(parameter), infos[0].help


def test_no_two_verbs_repeat_an_option_list() -> None:
    """Two verbs share at most one option they each declare themselves (an alias declared once, such as
    --stride or --camera-codec); a list of them is a group."""
    own = {
        verb: {_declaration(parameter) for parameter in _own_options(function).values()}
        for verb, function in _verbs().items()
    }
    shared = {
        (first, second): sorted(flags for flags, _ in mine & theirs)
        for (first, mine), (second, theirs) in itertools.combinations(own.items(), 2)
        if len(mine & theirs) > 1
    }
    assert shared == {}


def test_the_detecting_verbs_take_the_whole_detector_group() -> None:
    """A new detector setting (one option in `detector_options`, one field, one line) reaches every verb
    that judges with a detector, without touching them."""
    whole = set(DETECTOR.options()) - {"ray"}
    for verb in ("detect", "replay", "watch"):
        group = _verbs()[verb].option_groups["detector"]
        assert {p.name for p in group.parameters()} == whole, verb
    group = _verbs()["triage"].option_groups["detector"]
    assert {"k", "cache_dir", "device", "runtime"} <= {p.name for p in group.parameters()}


@pytest.mark.parametrize("build", list(GROUPS), ids=lambda build: build.__name__)
def test_every_field_of_a_value_has_its_option(build: Callable[..., Any]) -> None:
    """A value's fields and its group's options are one to one (a field without an option, or an option
    without a field, fails), and the group's defaults are the value's."""
    value, renamed = GROUPS[build]
    options = set(inspect.signature(build).parameters)
    fields = {field.name for field in dataclasses.fields(value)}
    made = {option for field in fields for option in renamed.get(field, (field,))}
    assert made == options
    required = [p.name for p in inspect.signature(build).parameters.values() if p.default is p.empty]
    assert build(**dict.fromkeys(required, Path("root"))) == value(*[Path("root")] * len(required))
    if build is detector_options:
        assert build() == DEFAULT_DETECTOR


def _verb_app(verb: Callable[..., Any]) -> typer.Typer:
    app = typer.Typer(add_completion=False)
    app.command("verb")(verb)
    app.command("other")(lambda: None)  # two commands: typer keeps the verb's name
    return app


def _point(x: int = 1, y: Annotated[int, typer.Option("--y", help="The y.")] = 2) -> tuple[int, int]:
    return x, y


def test_a_group_gives_its_value_in_its_options_place() -> None:
    """takes: the group's options on the command line, its value in the verb; without: the function's
    default; but: another declaration (help, default, name)."""
    seen: list[Any] = []
    point = OptionGroup(_point)

    @takes(
        point=point.without("x"), other=point.but(y=Declared(Annotated[int, typer.Option("--why")], 7, "why"))
    )
    def verb(*, point: tuple[int, int], other: tuple[int, int]) -> None:
        seen.append((point, other))

    result = CliRunner().invoke(_verb_app(verb), ["verb", "--y", "5", "--x", "3"])
    assert result.exit_code == 0, result.output
    assert seen == [((1, 5), (3, 7))]
    helped = CliRunner().invoke(_verb_app(verb), ["verb", "--help"], env={"COLUMNS": "200", "NO_COLOR": "1"})
    assert "--why" in helped.output and "The y." in helped.output and helped.output.count("--y ") == 1
    with pytest.raises(TypeError, match="declared twice"):
        takes(a=point, b=point)(lambda *, a, b: None)
    with pytest.raises(TypeError, match="has no option z"):
        point.without("z")


def test_calibrate_scores_as_detect_does() -> None:
    """calibrate and evaluate take the scoring options (K, modality) and where the encoder runs, and of the detector
    only the memory (and calibrate its encoder), never a rule or threshold: they set every rule's."""
    for verb, memory in (("calibrate", {"memory", "encoder"}), ("evaluate", {"memory"})):
        groups = _verbs()[verb].option_groups
        assert {p.name for p in groups["detector"].parameters()} == memory, verb
        assert {p.name for p in groups["scoring"].parameters()} == {"k", "modality"}, verb
        assert {"cache_dir", "device", "runtime"} <= {p.name for p in groups["placement"].parameters()}, verb
    assert _verbs()["build-memory"].option_groups.keys() == {"data", "recipe", "placement"}
    assert DETECTOR.parameters()[0].default is inspect.Parameter.empty  # --memory: required where it detects


#: For a group, a value other than the default for every one of its options, as given on the command line,
#: and the value the group must make of them.
GIVEN: dict[Callable[..., Any], tuple[list[str], Any]] = {
    recipe_options: (
        [
            "--encoder=timm:efficientnet_lite0",
            "--failure-frames=end",
            "--pairing=concat",
            "--success-step=0.1",
            "--signals=gripper_width",
            "--signal-features=change",
            "--signal-start-weight=0.25",
        ],
        MemoryRecipe(
            encoder="timm:efficientnet_lite0",
            failure_frames="end",
            pairing="concat",
            success_step=0.1,
            signals="gripper_width",
            signal_features="change",
            signal_start_weight=0.25,
        ),
    ),
    scoring_options: (["--k=7", "--modality=cameras"], Scoring(k=7, modality="cameras")),
    placement_options: (
        ["--cache-dir=embeddings", "--device=cpu", "--runtime=onnx", "--ray=local"],
        EncoderPlacement(device="cpu", runtime="onnx", cache_dir=Path("embeddings"), ray="local"),
    ),
    threshold_options: (
        ["--target-fpr=0.2", "--band=norm", "--fusion=per-view", "--band-scope=task"],
        ThresholdPolicy(target_fpr=0.2, band="norm", fusion="per-view", band_scope="task"),
    ),
}


@pytest.mark.parametrize("build", list(GIVEN), ids=lambda build: build.__name__)
def test_every_option_given_reaches_its_value(build: Callable[..., Any]) -> None:
    """Each option of a group, given a value other than its default on the command line, ends up in the
    value the verb receives (the test above compares defaults only: an option dropped between the command
    line and the value passes it)."""
    arguments, expected = GIVEN[build]
    flags = {
        flag
        for parameter in inspect.signature(build, eval_str=True).parameters.values()
        for flag in _flags(parameter)
    }
    assert {argument.split("=")[0] for argument in arguments} == flags  # every option is given
    default = build()
    changed = [field.name for field in dataclasses.fields(expected) if field.compare]
    assert all(getattr(expected, name) != getattr(default, name) for name in changed)
    seen: list[Any] = []

    @takes(value=OptionGroup(build))
    def verb(*, value: Any) -> None:
        seen.append(value)

    result = CliRunner().invoke(_verb_app(verb), ["verb", *arguments])
    assert result.exit_code == 0, result.output
    assert {name: getattr(seen[0], name) for name in changed} == {
        name: getattr(expected, name) for name in changed
    }


def test_target_fpr_is_declared_once() -> None:
    """Every verb that sets thresholds offers --target-fpr with the group's one help and one default."""
    offered = {}
    command_line: Any = typer.main.get_command(robofailring_app)
    for name, command in command_line.commands.items():
        for parameter in command.params:
            if "--target-fpr" in parameter.opts:
                offered[name] = (parameter.help, parameter.default)
    assert set(offered) == {"calibrate", "evaluate", "compare-encoders", "demo"}
    assert len(set(offered.values())) == 1
    assert next(iter(offered.values()))[1] == DEFAULT_TARGET_FPR == ThresholdPolicy().target_fpr


def test_a_verb_that_scores_takes_every_scoring_setting() -> None:
    """How runs are scored (`Scoring`: K, the modality, and any setting added to it later) is taken whole by every
    verb that takes any of it, so a new scoring setting reaches every verb that judges (detect, replay, watch,
    triage, calibrate, evaluate, compare, review, compare-encoders) with no verb's list edited (issue 53)."""
    scoring = set(SCORING.options())
    offered = {
        name: {parameter.name for parameter in inspect.signature(verb).parameters.values()}
        for name, verb in _verbs().items()
    }
    judging = {name for name, options in offered.items() if options & scoring}
    left_out = {
        "triage": {"modality"},  # it ranks episodes by their cameras (its references hold images)
        "compare-encoders": {"modality"},  # its table has each encoder's cameras alone and both side by side
    }
    assert {"detect", "replay", "watch", "triage", "calibrate", "evaluate", "compare", "review"} <= judging
    assert "compare-encoders" in judging
    missing = {name: scoring - offered[name] - left_out.get(name, set()) for name in judging}
    assert {name: sorted(names) for name, names in missing.items() if names} == {}
