"""`evaluate --folds` on data whose train/test split gives no held-out evaluation (a handful of labelled
runs whose successes all fell in the test split, say): the cross-validation over every labelled run,
which needs no split, alone, with the reason the held-out evaluation was not made."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from robofailring.atomic import write_text_atomic
from robofailring.data.model import Skipped
from robofailring.errors import SplitError
from robofailring.evaluation.folds import CrossValidation, cross_validate
from robofailring.evaluation.job import EvaluateConfig, evaluation_encoder, load_labelled
from robofailring.evaluation.markdown import skipped_inputs_markdown
from robofailring.outputs import EVALUATION_FORMAT


@dataclass(frozen=True)
class FoldsAlone:
    """The cross-validation of `evaluate --folds`, made without the held-out evaluation, and why."""

    name: str
    encoder: str
    held_out: str  # why no held-out evaluation was made: the split's error, as a sentence
    cross_validation: CrossValidation
    skipped_inputs: list[Skipped]

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": EVALUATION_FORMAT,  # what tells a re-run this file is its own (outputs.check_own_files)
            "name": self.name,
            "encoder": self.encoder,
            "held_out_evaluation": None,
            "held_out_not_made": self.held_out,
            "cross_validation": self.cross_validation.to_dict(),
            "skipped_inputs": [skipped.to_dict() for skipped in self.skipped_inputs],
        }

    def to_markdown(self) -> str:
        lines = [
            f"## {self.name} — encoder `{self.encoder}`, cross-validation only",
            "",
            f"**No held-out evaluation:** {self.held_out}. The cross-validation below judges every labelled run "
            "with a memory and thresholds of the other runs, whatever the split.",
            *self.cross_validation.to_markdown(),
        ]
        return "\n".join([*lines, *skipped_inputs_markdown(self.skipped_inputs)])


def cross_validate_alone(config: EvaluateConfig, held_out: SplitError) -> FoldsAlone:
    """`config`'s cross-validation (`config.folds`) over every run of `config.data`, for data whose split
    raised `held_out` before any held-out figure was made."""
    if config.folds is None:
        raise held_out
    dataset, _, skipped = load_labelled(config.data, vocabulary=config.data.read_vocabulary())
    encoder = evaluation_encoder(config)
    return FoldsAlone(
        name=config.name,
        encoder=config.recipe.encoder,
        held_out=str(held_out),
        cross_validation=cross_validate(config, list(dataset.trajectories()), encoder),
        skipped_inputs=skipped,
    )


def write_folds_alone(result: FoldsAlone, out: Path) -> tuple[Path, Path]:
    """<name>.json and <name>.md under `out`, written atomically (the names a full evaluation writes)."""
    json_path, md_path = Path(out) / f"{result.name}.json", Path(out) / f"{result.name}.md"
    write_text_atomic(json_path, json.dumps(result.to_dict(), indent=2), claim=True)
    write_text_atomic(md_path, result.to_markdown() + "\n", claim=True)
    return json_path, md_path
