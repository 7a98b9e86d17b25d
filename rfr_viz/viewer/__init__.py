"""The real Rerun viewer: headless screenshots, opening a recording at a frame, sharing recordings."""
