"""The paper's evaluation (§4): splits, runs, metrics, per-rule results, calibration and encoder comparison."""
