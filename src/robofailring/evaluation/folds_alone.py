"""`evaluate --folds` on data whose train/test split gives no held-out evaluation (a handful of labelled
runs whose successes all fell in the test split, say): the cross-validation over every labelled run,
which needs no split, alone, with the reason the held-out evaluation was not made (made by
`evaluation.job.cross_validate_alone`, written by `evaluation.written.write_evaluation`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from robofailring.data.model import Skipped
from robofailring.evaluation.folds import CrossValidation
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
