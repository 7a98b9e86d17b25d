"""The library's command-line verbs, their shared options and the exit statuses."""


def __getattr__(name: str) -> object:
    """The names of the old `robofailring.cli` module, which moved to `robofailring.cli.verbs` (deprecated)."""
    from robofailring._moved import moved_attribute

    return moved_attribute(__name__, "robofailring.cli.verbs", name)
