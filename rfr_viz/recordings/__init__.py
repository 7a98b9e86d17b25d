"""Recordings built from the panels: replay, comparison, live, closed loop, evaluation, and their blueprints."""
