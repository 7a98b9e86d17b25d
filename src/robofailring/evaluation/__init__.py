"""The paper's evaluation (§4): splits, runs, metrics, per-rule results, calibration and encoder comparison."""


def __getattr__(name: str) -> object:
    """The names of the old `robofailring.evaluation` module, which moved to `robofailring.evaluation.run` (deprecated)."""
    from robofailring._moved import moved_attribute

    return moved_attribute(__name__, "robofailring.evaluation.run", name)
