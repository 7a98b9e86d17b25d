"""The detector (paper §3.3): queries, per-view scores, the scoring rules and their thresholds, the live step API."""
