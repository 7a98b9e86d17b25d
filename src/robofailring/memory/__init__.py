"""The failure memory (paper Algorithm 1) and the success memory: their Faiss indexes, references, manifest and thinning."""


def __getattr__(name: str) -> object:
    """The names of the old `robofailring.memory` module, which moved to `robofailring.memory.failure` (deprecated)."""
    from robofailring._moved import moved_attribute

    return moved_attribute(__name__, "robofailring.memory.failure", name)
