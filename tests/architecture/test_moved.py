"""Old module paths import for one release, each with a DeprecationWarning naming the new path."""

from __future__ import annotations

import importlib
import json
import subprocess
import sys

import pytest

from rfr_viz._moved import MOVED as VIZ_MOVED
from robofailring._moved import MOVED as LIB_MOVED

MOVED = {**LIB_MOVED, **VIZ_MOVED}
LIGHT = sorted(old for old in MOVED if "closed_loop" not in old and "demo" not in old)  # no pybullet


FRESH = ["robofailring.detector", "robofailring.pipeline", "rfr_viz.replay"]


@pytest.fixture(scope="module")
def imported_fresh() -> dict[str, tuple[str, list[str]]]:
    """In one new interpreter: the project's own modules imported with deprecations as errors (key
    "project": the error, if any), then each old path of FRESH: its warnings and its public names."""
    probe = (
        "import warnings, json, importlib\n"
        "seen_by = {'project': ('', [])}\n"
        "try:\n"
        "    with warnings.catch_warnings():\n"
        "        warnings.simplefilter('error', DeprecationWarning)\n"
        "        import robofailring, rfr_viz, rfr_viz.cli.app, robofailring.cli.verbs\n"
        "        from robofailring.jobs import build_memory, detect\n"
        "        from rfr_viz.jobs import replay, review, watch, explain, compare_encoders\n"
        "except DeprecationWarning as error:\n"
        "    seen_by['project'] = (str(error), [])\n"
        "warnings.simplefilter('always')\n"
        f"for old in {FRESH!r}:\n"
        "    with warnings.catch_warnings(record=True) as seen:\n"
        "        warnings.simplefilter('always'); module = importlib.import_module(old)\n"
        "    seen_by[old] = ([str(w.message) for w in seen if w.category is DeprecationWarning],\n"
        "                    sorted(k for k in vars(module) if not k.startswith('_')))\n"
        "print(json.dumps(seen_by))"
    )
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout
    return {old: (" ".join(warned), names) for old, (warned, names) in json.loads(out).items()}


@pytest.mark.parametrize("old", FRESH)
def test_an_old_path_warns_and_holds_the_new_names(
    old: str, imported_fresh: dict[str, tuple[str, list[str]]]
) -> None:
    warned, names = imported_fresh[old]
    first = MOVED[old].split()[0]
    assert f"{old} moved to {first}" in warned
    new = importlib.import_module(first)
    public = [name for name in vars(new) if not name.startswith("_")]
    assert all(name in names for name in public)


def test_every_old_path_resolves_to_the_same_objects() -> None:
    for old in LIGHT:
        with pytest.warns(DeprecationWarning, match=old.replace(".", r"\.")):
            sys.modules.pop(old, None)
            module = importlib.import_module(old)
        first = importlib.import_module(MOVED[old].split()[0])  # the first named wins a shared name
        for name, value in vars(first).items():
            if not name.startswith("__"):
                assert getattr(module, name) is value, f"{old}.{name}"


def test_an_old_module_now_a_package_serves_its_names_with_a_warning() -> None:
    import robofailring.memory as memory
    from robofailring.memory.failure import FailureMemory

    with pytest.warns(DeprecationWarning, match=r"robofailring\.memory\.FailureMemory moved"):
        assert memory.FailureMemory is FailureMemory
    with pytest.raises(AttributeError):
        _ = memory.NoSuchName  # type: ignore[attr-defined]


def test_the_project_itself_uses_no_old_path(imported_fresh: dict[str, tuple[str, list[str]]]) -> None:
    assert imported_fresh["project"][0] == ""
