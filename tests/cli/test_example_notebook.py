"""examples/notebook.ipynb run end to end, as a user runs it, in a Jupyter kernel of this interpreter (nbclient).

Every wait has a limit: the kernel's start (`STARTUP_TIMEOUT`), each cell (`CELL_TIMEOUT`), and its
shutdown (jupyter_client kills a kernel that does not stop). No frontend is attached, so the
viewer widgets are created and displayed but never load: what is checked is what a frontend gets.
"""

from __future__ import annotations

import ast
import json
import os
import re
import sys
from pathlib import Path
from typing import Any

import pytest
from environment import require_module

from robofailring import RULES
from robofailring.evaluation.metrics import PAPER_DELTAS
from robofailring.outputs import is_recording

pytestmark = pytest.mark.slow  # simulation and a kernel: the full lane only (scripts/test.sh)

nbformat = require_module("nbformat", "pip install -e '.[dev]' (scripts/setup.sh --dev)")
nbclient = require_module("nbclient", "pip install -e '.[dev]' (scripts/setup.sh --dev)")
require_module("rerun_notebook", "pip install -e '.[notebook]'")

NOTEBOOK = Path(__file__).resolve().parents[2] / "examples" / "notebook.ipynb"
CELL_TIMEOUT = 300  # seconds, any one cell (the whole notebook takes about 30 s on 2 cores)
STARTUP_TIMEOUT = 120  # seconds for the kernel to start and answer
WIDGET = "application/vnd.jupyter.widget-view+json"
WIDGET_STATE = "application/vnd.jupyter.widget-state+json"


def _kernel_manager(folder: Path) -> Any:
    """A kernel manager whose only `python3` kernel is this interpreter (not whatever `python` is on PATH)."""
    from jupyter_client.kernelspec import KernelSpecManager
    from jupyter_client.manager import KernelManager

    spec = folder / "kernels" / "python3"
    spec.mkdir(parents=True)
    argv = [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"]
    (spec / "kernel.json").write_text(
        json.dumps({"argv": argv, "display_name": "this interpreter", "language": "python"})
    )
    specs = KernelSpecManager(kernel_dirs=[str(folder / "kernels")], ensure_native_kernel=False)
    return KernelManager(kernel_name="python3", kernel_spec_manager=specs, shutdown_wait_time=10)


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Any, Path]:
    """The notebook executed in a fresh folder (its working directory), and that folder."""
    tmp = tmp_path_factory.mktemp("notebook")
    work = tmp / "work"
    work.mkdir()
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    client = nbclient.NotebookClient(
        notebook,
        km=_kernel_manager(tmp),
        kernel_name="python3",
        timeout=CELL_TIMEOUT,
        startup_timeout=STARTUP_TIMEOUT,
        allow_errors=True,  # every cell runs; the test names the ones that failed
        resources={"metadata": {"path": str(work)}},
    )
    env = {
        **os.environ,  # PYTHONPATH among them: a worktree's code
        "ROBOFAILRING_CACHE": str(tmp / "cache"),
        "ROBOFAILRING_PROGRESS": "0",
    }
    client.execute(env=env)
    return notebook, work


def _code_cells(notebook: Any) -> list[Any]:
    return [cell for cell in notebook.cells if cell.cell_type == "code"]


def _cell(notebook: Any, needle: str) -> Any:
    (found,) = [cell for cell in _code_cells(notebook) if needle in cell.source]
    return found


def _stdout(cell: Any) -> str:
    return "".join(output.text for output in cell.outputs if output.output_type == "stream")


def _tables(cell: Any) -> list[list[dict[str, Any]]]:
    """The tables `show_table` printed: one dict per row (plain rows), or a DataFrame's text, parsed."""
    tables: list[list[dict[str, Any]]] = []
    for output in cell.outputs:
        if output.output_type == "stream":
            for line in output.text.splitlines():
                if line.startswith("{"):
                    tables[-1].append(ast.literal_eval(line))
                elif line.endswith(":"):
                    tables.append([])
        elif output.output_type == "display_data" and "text/plain" in output.data:
            header, *lines = output.data["text/plain"].splitlines()
            names = header.split()
            for line in lines:
                values = line.split()[1:]  # the DataFrame's index first
                tables[-1].append(
                    {
                        name: value if name == "rule" else float(value)
                        for name, value in zip(names, values, strict=True)
                    }
                )
    return tables


def test_every_cell_ran_without_error(run: tuple[Any, Path]) -> None:
    notebook, _ = run
    cells = _code_cells(notebook)
    assert len(cells) == 7
    errors = [
        f"cell {index}: {output.ename}: {output.evalue}"
        for index, cell in enumerate(cells)
        for output in cell.outputs
        if output.output_type == "error"
    ]
    assert errors == []
    assert [cell.execution_count for cell in cells] == list(range(1, len(cells) + 1))


def test_the_dataset_and_the_evaluation_are_the_small_ones(run: tuple[Any, Path]) -> None:
    notebook, work = run
    printed = _stdout(_cell(notebook, "rfr.generate_dataset("))
    assert re.match(r"13 episodes \(7 failures\) in ", printed), (
        printed
    )  # one per failure family, 6 successes
    printed = _stdout(_cell(notebook, "rfr.run_evaluation("))
    assert f"memory: {Path('notebook-run') / 'evaluation' / 'memory'}" in printed
    assert (work / "notebook-run" / "evaluation" / "memory" / "manifest.json").is_file()


def test_the_tables_hold_every_rule_and_the_paper_deltas(run: tuple[Any, Path]) -> None:
    notebook, _ = run
    counts = re.search(
        r"(\d+) failure and (\d+) success test trajectories", _stdout(_cell(notebook, "rfr.run_evaluation("))
    )
    assert counts is not None
    failures, successes = int(counts[1]), int(counts[2])
    assert failures > 0 and successes > 0
    rules, deltas = _tables(_cell(notebook, 'show_table("Every scoring rule'))
    assert [row["rule"] for row in rules] == list(
        RULES
    )  # paper, contrast, novelty: a memory with success runs
    for row in rules:
        assert (row["tp"] + row["fn"], row["fp"] + row["tn"]) == (failures, successes), row
        assert row["recall"] == pytest.approx(row["tp"] / failures, abs=1e-6)
        assert row["fpr"] == pytest.approx(row["fp"] / successes, abs=1e-6)
        assert 0.0 <= row["auc"] <= 1.0
    assert [row["delta"] for row in deltas] == pytest.approx(list(PAPER_DELTAS))
    recalls = [row["recall"] for row in deltas]
    assert recalls == sorted(recalls, reverse=True)  # a higher δ never detects more
    assert all(row["tp"] + row["fn"] == failures for row in deltas)


def test_the_detector_ran_on_four_test_episodes(run: tuple[Any, Path]) -> None:
    notebook, _ = run
    lines = _stdout(_cell(notebook, "rfr.open_detector(")).splitlines()
    assert len(lines) == 4, lines
    for line in lines:
        assert re.fullmatch(
            r"pick_cube/pick_cube_\w+ \[\w+\]: (no alarm|alarm at frame \d+ \(\w+\))", line
        ), line


def test_each_show_cell_holds_the_viewer_widget_once(run: tuple[Any, Path]) -> None:
    notebook, work = run
    state = notebook.metadata["widgets"][WIDGET_STATE]["state"]
    viewers = {
        model_id
        for model_id, model in state.items()
        if model["state"].get("_width") == "auto" and model["state"].get("_height") == "auto"
    }
    for needle in ("rfr_viz.show(traces[", "rfr_viz.show(summary_recording)"):
        cell = _cell(notebook, needle)
        assert not [output for output in cell.outputs if output.output_type == "execute_result"]  # shown once
        shown = [
            output.data[WIDGET]["model_id"] for output in cell.outputs if WIDGET in output.get("data", {})
        ]
        assert shown, cell.outputs
        boxes = [
            state[model_id]["state"] for model_id in shown if state[model_id]["model_name"] == "VBoxModel"
        ]
        assert len(boxes) == 1
        children = {child.removeprefix("IPY_MODEL_") for child in boxes[0]["children"]}
        assert len(children & viewers) == 1  # the rerun-notebook viewer sits in the box
    assert is_recording(work / "notebook-run" / "evaluation" / "summary.rrd")
