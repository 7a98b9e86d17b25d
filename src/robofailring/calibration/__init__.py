"""Calibration: every rule's threshold set split-conformally on success runs (docs/rules.md, "Calibration with a
guarantee").

`conformal` (the threshold, its FPR spread, the AUC), `bands` (time-indexed bands fitted on the calibration runs),
`fusions` (how the views meet one threshold, one class per fusion), `policy` (`ThresholdPolicy`, how a job sets
thresholds) and `job` (`calibrate`, the calibration job, and `calibrate_rules`, which the evaluation runs per
split or fold). The detector applies what calibration stored (`robofailring.detection.band`, `detection.stored`)
and never imports this package.
"""
