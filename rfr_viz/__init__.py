"""Rerun recordings of replayed trajectories (all Rerun code of the project lives here)."""

from __future__ import annotations
