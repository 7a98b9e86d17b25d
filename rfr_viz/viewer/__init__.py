"""The real Rerun viewer: headless screenshots, opening a recording at a frame, sharing recordings."""


def __getattr__(name: str) -> object:
    """The names of the old `rfr_viz.viewer` module, which moved to `rfr_viz.viewer.control` (deprecated)."""
    from robofailring._moved import moved_attribute

    return moved_attribute(__name__, "rfr_viz.viewer.control", name)
