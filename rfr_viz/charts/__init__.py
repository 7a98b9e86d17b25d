"""The evaluation's charts: drawn once as data, rendered in Rerun, as SVG and in report.html."""
