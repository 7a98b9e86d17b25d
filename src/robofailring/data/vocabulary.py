"""A vocabulary file: a dataset's own failure symbols and stage words, extending Table 5.

JSON or YAML (by suffix: `.json`, else YAML), one object::

    symbols:                    # symbol -> the words for its cause ("The failure was caused by …")
      knocked_cup: the gripper knocking the cup over
      drawer_timeout: a timeout while opening the drawer
    stages:                     # optional: words for stage numbers (wp<N>, stage<N> or <N>)
      1: approach to the drawer

A symbol is lower-case words joined by `_`; it may not repeat (also differing only in case) nor
redefine a Table 5 symbol; a sentence may not be empty. Each fault is a VocabularyError naming the
file and the key. YAML aliases (`*name`) are refused, as are keys that are not text or a number: an
alias repeats a node, so a few lines of them can stand for billions of words. A memory keeps its
vocabulary as `vocabulary.json` in its folder.
"""

from __future__ import annotations

import re
import reprlib
from pathlib import Path
from typing import Any, Final

from robofailring.data.grounding import Vocabulary, reserved_symbols
from robofailring.errors import VocabularyError
from robofailring.jsontext import parse_json

_SYMBOL: Final = re.compile(r"^[a-z][a-z0-9]*(_[a-z0-9]+)*$")
_KEYS: Final[frozenset[str]] = frozenset({"symbols", "stages"})


def read_vocabulary(path: Path) -> Vocabulary:
    """The vocabulary in `path`; VocabularyError naming the file and the fault, nothing half-read."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as error:
        raise VocabularyError(f"cannot read vocabulary file {path}: {error}") from error
    loaded = _load_json(text, path) if path.suffix.lower() == ".json" else _load_yaml(text, path)
    return vocabulary_from(loaded, where=str(path))


def vocabulary_from(loaded: Any, *, where: str) -> Vocabulary:
    """A vocabulary from its parsed object (`{"symbols": {…}, "stages": {…}}`), checked."""
    if not isinstance(loaded, dict) or "symbols" not in loaded:
        raise VocabularyError(f"vocabulary {where} must be an object with 'symbols' (and optional 'stages')")
    unknown = sorted(str(key) for key in loaded if key not in _KEYS)
    if unknown:
        raise VocabularyError(
            f"vocabulary {where}: unknown key {unknown[0]!r} (it holds 'symbols' and 'stages')"
        )
    symbols = _section(loaded["symbols"], where=where, name="symbols")
    if not symbols:
        raise VocabularyError(f"vocabulary {where} defines no symbol")
    own: dict[str, str] = {}
    for key, words in symbols:
        symbol = str(key).strip().lower()
        if not _SYMBOL.match(symbol):
            raise VocabularyError(
                f"vocabulary {where}: symbol {key!r} is not lower-case words joined by '_' (e.g. knocked_cup)"
            )
        if symbol in reserved_symbols():
            raise VocabularyError(
                f"vocabulary {where}: symbol {key!r} is already a Table 5 symbol; name your own differently"
            )
        if symbol in own:
            raise VocabularyError(f"vocabulary {where}: symbol {key!r} is defined twice")
        own[symbol] = _sentence(words, where=where, key=key)
    stages: dict[int, str] = {}
    for key, words in _section(loaded.get("stages", {}), where=where, name="stages"):
        try:
            stage = int(str(key))
        except ValueError as error:
            raise VocabularyError(f"vocabulary {where}: stage {key!r} is not a stage number") from error
        if stage < 0 or stage in stages:
            raise VocabularyError(f"vocabulary {where}: stage {key!r} is negative or defined twice")
        stages[stage] = _sentence(words, where=where, key=key)
    return Vocabulary(symbols=own, stages=stages)


def _section(value: Any, *, where: str, name: str) -> list[tuple[Any, Any]]:
    if isinstance(value, _Pairs):
        return list(value.pairs)
    if isinstance(value, dict):
        return list(value.items())
    raise VocabularyError(f"vocabulary {where}: {name!r} must be an object (key: words)")


def _sentence(words: Any, *, where: str, key: Any) -> str:
    if not isinstance(words, str) or not words.strip():
        shown = reprlib.repr(words)
        raise VocabularyError(f"vocabulary {where}: {key!r} has an empty sentence (or not text: {shown})")
    return " ".join(words.split()).rstrip(".")


class _Pairs(dict[Any, Any]):
    """A mapping as the file wrote it: every key in order, repeated ones kept (to refuse them)."""

    def __init__(self, pairs: list[tuple[Any, Any]]) -> None:
        super().__init__(pairs)
        self.pairs = pairs


def _load_json(text: str, path: Path) -> Any:
    return parse_json(text, source=f"vocabulary file {path}", error=VocabularyError, object_pairs_hook=_Pairs)


def _load_yaml(text: str, path: Path) -> Any:
    """YAML with libyaml where PyYAML has it (PyPI's wheels do): the pure-Python scanner takes time
    quadratic in the nesting, ~1 s to refuse a line of 1,000 brackets; libyaml refuses nesting past
    its limit at once. Aliases are refused from the event stream, before anything is built."""
    import yaml

    base: type[yaml.SafeLoader] = getattr(yaml, "CSafeLoader", yaml.SafeLoader)

    class PairsLoader(base):
        pass

    def pairs(loader: yaml.SafeLoader, node: yaml.MappingNode) -> _Pairs:
        found = []
        for key_node, value_node in node.value:
            key = loader.construct_object(key_node, deep=True)
            if not isinstance(key, str | int | float | bool | None):
                raise VocabularyError(
                    f"vocabulary file {path}, line {key_node.start_mark.line + 1}: a key is "
                    f"{reprlib.repr(key)}, not a symbol or a stage number"
                )
            found.append((key, loader.construct_object(value_node)))
        return _Pairs(found)

    PairsLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, pairs)
    try:
        for event in yaml.parse(text, Loader=base):
            if isinstance(event, yaml.AliasEvent):
                raise VocabularyError(
                    f"vocabulary file {path}, line {event.start_mark.line + 1}: the YAML alias *{event.anchor} "
                    "is not allowed (write each sentence out)"
                )
        return yaml.load(text, Loader=PairsLoader)
    except yaml.YAMLError as error:
        if "maximum nesting depth" in str(error):
            raise VocabularyError(f"vocabulary file {path} nests lists or objects too deeply") from error
        raise VocabularyError(f"vocabulary file {path} is not valid YAML: {error}") from error
    except RecursionError as error:
        raise VocabularyError(f"vocabulary file {path} nests lists or objects too deeply") from error
