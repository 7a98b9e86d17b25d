"""Option groups: options declared once, as the parameters of the one function that turns them into a value.

A group is a function such as `detector_options(memory: MemoryOption, k: KOption = 5, …) -> DetectorConfig`.
A verb lists the groups it takes, each under the name of the parameter that receives its value::

    @app.command("detect")
    @takes(detector=DETECTOR, data=DATA.without("vocabulary"))
    def detect_cmd(data: DataSelection, detector: DetectorConfig, as_json: …) -> None: …

and its command line gets the group's options in that parameter's place (typer reads the signature
`takes` writes). A verb may leave some of a group's options out (`without`, `only`: the function's
defaults stand for them) or declare one for itself (`but`: its own help, default or name), never list
them again; so a new setting of a group is one option, one field and one line, in every verb that
takes it. A group's options are listed under its `panel` in `--help` (and in docs/cli.md's reference), the
verb's own under "Options". A value made of other values takes their groups as `parts`: `DETECTOR`'s function
receives the `EncoderPlacement` that `ENCODER`'s options make, and a verb taking `DETECTOR` gets those options
too, under their own panel, left out or declared by their names as its own are.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import inspect
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Annotated, Any, Generic, TypeVar, get_origin

from typer.models import OptionInfo

Value = TypeVar("Value")
Verb = TypeVar("Verb", bound=Callable[..., Any])
REQUIRED = inspect.Parameter.empty  # a `Declared` default: the option (or argument) must be given


@dataclass(frozen=True)
class Declared:
    """One of a group's parameters as one verb declares it: its typer annotation (`Annotated[…, typer.Option(…)]`),
    its default (`REQUIRED`: none), and the name the verb's command line knows it by (an argument's)."""

    annotation: Any
    default: Any = REQUIRED
    name: str | None = None


@dataclass(frozen=True)
class OptionGroup(Generic[Value]):
    """Options declared once, as the parameters of `build`, turned into one value by it, and listed under
    `panel` in `--help`."""

    build: Callable[..., Value]
    panel: str = (
        ""  # the heading its options are listed under in --help, as docs/cli.md names it; "": "Options"
    )
    left_out: frozenset[str] = frozenset()  # parameters this verb does not offer: `build`'s defaults stand
    declared: Mapping[str, Declared] = field(
        default_factory=dict
    )  # parameters this verb declares its own way
    # parameters of `build` that are another group's value: that group's options are offered in their place
    parts: Mapping[str, OptionGroup[Any]] = field(default_factory=dict)

    def without(self, *names: str) -> OptionGroup[Value]:
        """The group less the options `names` (parameter names of `build` or of its parts')."""
        self._check(names)
        return dataclasses.replace(
            self,
            left_out=self.left_out | (set(names) - self._in_parts()),
            parts={
                part: group.without(*(name for name in names if name in group.options()))
                for part, group in self.parts.items()
            },
        )

    def only(self, *names: str) -> OptionGroup[Value]:
        """The group with only the options `names`."""
        self._check(names)
        return self.without(*(name for name in self.options() if name not in names))

    def but(self, **declarations: Declared) -> OptionGroup[Value]:
        """The group with some of its parameters declared for one verb (their help, default, name)."""
        self._check(declarations)
        parts = {
            part: group.but(**{name: own for name, own in declarations.items() if name in group.options()})
            for part, group in self.parts.items()
        }
        own = {name: declared for name, declared in declarations.items() if name not in self._in_parts()}
        return dataclasses.replace(self, declared={**self.declared, **own}, parts=parts)

    def options(self) -> list[str]:
        """Every option the group can offer, its parts' in their place, by their parameter names."""
        names: list[str] = []
        for name in self._signature().parameters:
            names += self.parts[name].options() if name in self.parts else [name]
        return names

    def parameters(self) -> list[inspect.Parameter]:
        """The parameters a verb's command line gets: `build`'s, less those left out, as declared."""
        offered = []
        for name, parameter in self._signature().parameters.items():
            if name in self.parts:
                offered += self.parts[name].parameters()
                continue
            if name in self.left_out:
                continue
            own = self.declared.get(name)
            if own is not None:
                parameter = parameter.replace(
                    name=own.name or name, annotation=own.annotation, default=own.default
                )
            offered.append(
                parameter.replace(
                    kind=inspect.Parameter.KEYWORD_ONLY,
                    annotation=_in_panel(parameter.annotation, self.panel),
                )
            )
        return offered

    def panels(self) -> dict[str, str]:
        """The panel each offered option is listed under in `--help`, by the name `parameters` gives it."""
        found = {parameter.name: self.panel for parameter in self.parameters()}
        for group in self.parts.values():
            found.update(group.panels())
        return found

    def value(self, given: Mapping[str, Any]) -> Value:
        """`build` of the options given (by the names `parameters` gave them)."""
        rest = dict(given)
        made = {
            part: group.value({p.name: rest.pop(p.name) for p in group.parameters() if p.name in rest})
            for part, group in self.parts.items()
        }
        names = {own.name: name for name, own in self.declared.items() if own.name is not None}
        return self.build(**{names.get(name, name): option for name, option in rest.items()}, **made)

    def _signature(self) -> inspect.Signature:
        return inspect.signature(self.build, eval_str=True)

    def _in_parts(self) -> set[str]:
        return {name for group in self.parts.values() for name in group.options()}

    def _check(self, names: Any) -> None:
        unknown = sorted(set(names) - set(self.options()))
        if unknown:
            raise TypeError(f"{self.build.__name__} has no option {', '.join(unknown)}")


def _in_panel(annotation: Any, panel: str) -> Any:
    """An option's `Annotated[…, typer.Option(…)]` with `rich_help_panel=panel` (arguments stay under
    "Arguments"; an option that names its own panel keeps it)."""
    if not panel or get_origin(annotation) is not Annotated:
        return annotation
    metadata = []
    for info in annotation.__metadata__:
        if isinstance(info, OptionInfo) and info.rich_help_panel is None:
            info = copy.copy(info)
            info.rich_help_panel = panel
        metadata.append(info)
    return Annotated[(annotation.__origin__, *metadata)]


def takes(**groups: OptionGroup[Any]) -> Callable[[Verb], Verb]:
    """The verb's parameter `name` receives the value of `groups[name]`, whose options its command line
    gets in that parameter's place."""

    def decorate(verb: Verb) -> Verb:
        own = inspect.signature(verb, eval_str=True).parameters
        missing = sorted(set(groups) - set(own))
        if missing:
            raise TypeError(f"{verb.__name__} has no parameter {', '.join(missing)} for its option groups")
        offered: list[inspect.Parameter] = []
        of_group: dict[str, list[str]] = {}
        for name, parameter in own.items():
            if name in groups:
                group_parameters = groups[name].parameters()
                of_group[name] = [p.name for p in group_parameters]
                offered += group_parameters
            else:
                offered.append(parameter.replace(kind=inspect.Parameter.KEYWORD_ONLY))
        names = [parameter.name for parameter in offered]
        twice = sorted({name for name in names if names.count(name) > 1})
        if twice:
            raise TypeError(f"{verb.__name__}: parameter {', '.join(twice)} is declared twice")

        @functools.wraps(verb)
        def command(**given: Any) -> Any:
            for name, group in groups.items():
                given[name] = group.value({option: given.pop(option) for option in of_group[name]})
            return verb(**given)

        command.__signature__ = inspect.Signature(offered)  # type: ignore[attr-defined]
        command.__annotations__ = {parameter.name: parameter.annotation for parameter in offered}
        command.option_groups = dict(groups)  # type: ignore[attr-defined]
        return command  # type: ignore[return-value]

    return decorate
