"""`--ray ADDRESS` is one option (robofailring.cli.option_groups.RayOption), offered by the verbs that encode a dataset."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from rfr_viz.cli.app import app


@pytest.mark.parametrize("verb", ["build-memory", "evaluate"])
def test_the_verbs_that_encode_a_dataset_take_ray(verb: str) -> None:
    result = CliRunner().invoke(app, [verb, "--help"], env={"COLUMNS": "200", "NO_COLOR": "1"})
    assert result.exit_code == 0
    assert "--ray" in result.output and "ADDRESS" in result.output and "ray://host:port" in result.output
