"""The verbs that record, and the one robofailring command assembled from every verb app."""


def __getattr__(name: str) -> object:
    """The names of the old `rfr_viz.cli` module, which moved to `rfr_viz.cli.app` (deprecated)."""
    from robofailring._moved import moved_attribute

    return moved_attribute(__name__, "rfr_viz.cli.app", name)
