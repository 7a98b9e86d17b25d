"""Old module paths still import for one release, each with a DeprecationWarning naming its new path.

The modules moved into one package per concept (docs/architecture.md). `install` puts a finder in
front of the import system that serves an old path as a module holding the new module's names;
`moved_attribute` serves the names of an old module whose path is now a package's.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys
import warnings
from collections.abc import Mapping, Sequence
from types import ModuleType
from typing import Final

# old path -> new path(s): an old module whose contents were split names each new one, space-separated
MOVED: Final[Mapping[str, str]] = dict(
    {
        "robofailring.calibration": "robofailring.evaluation.calibration",
        "robofailring.cli_options": "robofailring.cli.options",
        "robofailring.comparison": "robofailring.evaluation.comparison",
        "robofailring.detector": "robofailring.detection.detector",
        "robofailring.evaluation_result": "robofailring.evaluation.result",
        "robofailring.exit_codes": "robofailring.cli.exit_codes",
        "robofailring.grounding": "robofailring.data.grounding",
        "robofailring.memory_format": "robofailring.memory.format",
        "robofailring.memory_info": "robofailring.memory.info",
        "robofailring.memory_manifest": "robofailring.memory.manifest",
        "robofailring.metrics": "robofailring.evaluation.metrics robofailring.detection.conformal",
        "robofailring.pipeline": "robofailring.jobs.build_memory robofailring.jobs.detect",
        "robofailring.references": "robofailring.memory.references",
        "robofailring.report": "robofailring.explain.report",
        "robofailring.rule_evaluation": "robofailring.evaluation.per_rule",
        "robofailring.scoring": "robofailring.detection.rules robofailring.detection.conformal",
        "robofailring.sim.closed_loop": "robofailring.jobs.closed_loop",
        "robofailring.success_memory": "robofailring.memory.success",
        "robofailring.task_index": "robofailring.memory.index",
        "robofailring.thinning": "robofailring.memory.thinning",
        "robofailring.trace": "robofailring.detection.trace robofailring.detection.detector",
        "robofailring.view_scores": "robofailring.detection.view_scores",
        "robofailring.vlm": "robofailring.explain.vlm",
    }
)


def _warn(old: str, new: str, *, stacklevel: int) -> None:
    warnings.warn(
        f"{old} moved to {new}; import it from there (the old path goes in the next release)",
        DeprecationWarning,
        stacklevel=stacklevel,
    )


class _MovedFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Serves each old module path as a module with the new module's public names."""

    def __init__(self, moved: Mapping[str, str]) -> None:
        self.moved = dict(moved)

    def find_spec(
        self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        if fullname not in self.moved:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType | None:
        return None  # the default module; exec_module fills it

    def exec_module(self, module: ModuleType) -> None:
        new = self.moved[module.__name__].split()
        _warn(module.__name__, " and ".join(new), stacklevel=3)  # importlib frames are skipped
        for name in reversed(new):  # the first named wins a name both hold
            target = importlib.import_module(name)
            module.__dict__.update({k: v for k, v in vars(target).items() if not k.startswith("__")})
        module.__doc__ = f"Deprecated: moved to {' and '.join(new)}."


def install(moved: Mapping[str, str]) -> None:
    """Serve these old module paths (old -> new) from now on; installing a table twice changes nothing."""
    for finder in sys.meta_path:
        if isinstance(finder, _MovedFinder):
            finder.moved.update(moved)
            return
    sys.meta_path.insert(0, _MovedFinder(moved))


def moved_attribute(package: str, module: str, name: str) -> object:
    """`package.name`, where `package` was a module whose contents moved to `module` (a package's __getattr__)."""
    if name.startswith("__"):
        raise AttributeError(f"module {package!r} has no attribute {name!r}")
    target = importlib.import_module(module)
    if not hasattr(target, name):
        raise AttributeError(f"module {package!r} has no attribute {name!r}")
    _warn(f"{package}.{name}", f"{module}.{name}", stacklevel=4)  # the package __getattr__'s caller
    return getattr(target, name)


install(MOVED)
