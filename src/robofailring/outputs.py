"""Output paths are checked before any work: never a file, never the input, never a folder of other things.

A verb writes only into a folder that is absent, empty, or already its own kind of output (a
failure memory, a folder of recordings), never into, over or around its input, and never over
the current folder. Every refusal is an `OutputError` naming the path and what to do instead.
"""

from __future__ import annotations

import os
import re
import tempfile
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Final

from robofailring.errors import DataError, OutputError, WriteError
from robofailring.jsontext import parse_json

MEMORY_MANIFEST: Final[str] = "manifest.json"
RRD_MAGIC: Final[bytes] = b"RRF"  # every Rerun .rrd file starts with RRF0/RRF1/RRF2
# a `--name`'s UTF-8 bytes: its files' and their temporary files' names (`.<name>.json.rfr-XXXXXXXX.tmp`) stay
# within the 255 bytes most file systems allow
MAX_STEM_BYTES: Final[int] = 200


def is_memory_dir(path: Path) -> bool:
    """True when `path` holds a failure memory's manifest (a JSON object with an encoder and a version)."""
    manifest_path = Path(path) / MEMORY_MANIFEST
    try:
        manifest = parse_json(manifest_path.read_bytes(), source=str(manifest_path))
    except (OSError, DataError):
        return False
    return isinstance(manifest, dict) and "format_version" in manifest and "encoder" in manifest


def is_recording(path: Path) -> bool:
    """True when `path` is a file that starts like a Rerun recording."""
    try:
        with Path(path).open("rb") as handle:
            return handle.read(len(RRD_MAGIC)) == RRD_MAGIC
    except OSError:
        return False


def _within(inner: Path, outer: Path) -> bool:
    return inner == outer or outer in inner.parents


def check_not_input(
    out: Path, inputs: Iterable[Path | None], *, replaces: bool = True, flag: str = "--out"
) -> Path:
    """Refuse an output that is or lies inside an input; one that `replaces` its folder may not hold
    an input or the current folder either."""
    resolved = Path(out).expanduser().resolve()
    if replaces and _within(Path.cwd().resolve(), resolved):
        raise OutputError(
            f"{flag} {out} is the current folder or holds it; name a new folder, e.g. {flag} out"
        )
    for given in inputs:
        if given is None:
            continue
        source = Path(given).expanduser().resolve()
        if _within(resolved, source) or (replaces and _within(source, resolved)):
            relation = (
                "is" if resolved == source else ("lies inside" if _within(resolved, source) else "holds")
            )
            raise OutputError(
                f"{flag} {out} {relation} the input {given}; writing there could destroy it, choose a folder outside it"
            )
    return resolved


def check_file_stem(name: str, *, flag: str = "--name") -> str:
    """`name` unchanged when it can only name a file inside the output folder (`<name>.json`, …): not
    blank, no path separator, no leading dot (no `..`, no hidden files), no control or other unprintable
    character (a newline), at most `MAX_STEM_BYTES` in UTF-8; else OutputError naming it, before any work."""
    if len(name.encode("utf-8", "surrogatepass")) > MAX_STEM_BYTES:
        raise OutputError(
            f"{flag} {name[:40]!r}… is {len(name.encode('utf-8', 'surrogatepass'))} bytes long: a name of at "
            f"most {MAX_STEM_BYTES} bytes leaves room for the suffixes its files take within a file system's "
            "255-byte file names"
        )
    if not name.strip() or name.startswith(".") or any(character in name for character in "/\\\0"):
        raise OutputError(
            f"{flag} {name!r} is not a plain file name: give a name without /, \\ or a leading dot "
            f"(it names the files written into --out, e.g. {flag} evaluation)"
        )
    if not name.isprintable():
        raise OutputError(
            f"{flag} {name!r} is not a plain file name: it has a control or unprintable character (a newline, "
            "a tab, …), which file names and the lines that list them cannot show"
        )
    return name


def check_writable(folder: Path) -> None:
    """Prove a file can be written in `folder`, or in the folder that would hold it, before any long work.

    Nothing is created: a refused or failed command leaves no empty output folder behind; the
    writers make the folder when they write its first file.
    """
    folder = Path(folder).absolute()
    existing = next(
        (
            candidate
            for candidate in (folder, *folder.parents)
            if candidate.exists() or candidate.is_symlink()
        ),
        Path(folder.anchor),
    )
    if not existing.is_dir():
        why = (
            "a file is in the way of that folder"
            if existing == folder
            else "part of that path is a file, not a folder"
        )
        raise OutputError(f"cannot write into {folder}: {why}")
    try:
        fd, probe = tempfile.mkstemp(prefix=".robofailring-probe.", dir=existing)
        os.close(fd)
        os.unlink(probe)
    except OSError as error:
        reason = (error.strerror or type(error).__name__).lower()
        place = "" if existing == folder else f" (it would be made in {existing})"
        raise WriteError(
            f"cannot write into {folder}{place}: {reason}; choose a folder you can write to"
        ) from error


def check_folder(folder: Path, *, holds: str, flag: str = "--out") -> None:
    """Refuse a folder option that names a file or lies under one (`--data-dir notes.txt`): OutputError naming
    the option, the path and what the folder `holds`, before any work (not `File exists` half-way through)."""
    folder = Path(folder)
    blocking = next((p for p in (folder, *folder.parents) if p.exists() or p.is_symlink()), None)
    if blocking is None or blocking.is_dir():
        return
    where = "is a file" if blocking == folder else f"cannot be made: part of that path is a file ({blocking})"
    raise OutputError(f"{flag} {folder} {where}; {holds} is a folder: choose another {flag}")


def check_memory_target(out: Path, *, inputs: Iterable[Path | None] = ()) -> None:
    """A memory may be written at `out` only if it is absent, an empty folder or another memory."""
    check_not_input(out, inputs)
    out = Path(out)
    check_folder(out, holds="a memory")
    if out.is_dir() and not is_memory_dir(out):
        names = sorted(entry.name for entry in out.iterdir())
        if names:
            shown = ", ".join(names[:3]) + (" …" if len(names) > 3 else "")
            raise OutputError(
                f"--out {out} is a folder that is not a failure memory (it holds {shown}); "
                "refusing to replace it: choose a new or empty folder"
            )
    check_writable(out.absolute().parent)


def check_output_folder(out: Path, *, inputs: Iterable[Path | None] = ()) -> None:
    """Files (recordings, tables) may go into `out` if it is, or can be made, a writable folder outside the inputs."""
    check_not_input(out, inputs, replaces=False)
    check_folder(out, holds="this output")
    check_writable(out)


_OWN_HTML: Final[bytes] = b"<title>RoboFailRing"  # every page the project writes (report.html, triage.html)
_OWN_MARKDOWN: Final[re.Pattern[str]] = re.compile(r"## .+ \u2014 encoder `")  # an evaluation's first line
EVALUATION_FORMAT: Final[str] = "robofailring-evaluation"  # `format` of every evaluation's JSON
# what an evaluation's JSON held before it said its format: every version's keys (a held-out evaluation,
# the cross-validation alone), so a re-run replaces them and a user's `{"name", "encoder"}` is not taken
_EARLIER_JSON_KEYS: Final[tuple[frozenset[str], ...]] = (
    frozenset({"name", "encoder", "memory", "k", "operating_delta", "calibrated", "failures", "successes"}),
    frozenset({"name", "encoder", "held_out_evaluation", "held_out_not_made", "cross_validation"}),
)


def _written_here(path: Path) -> bool:
    """Whether `path` reads as one of the project's own tables or pages (by its suffix): an HTML page
    titled RoboFailRing, an evaluation's Markdown (its `## <name> — encoder` heading first) or JSON (its
    `format`, or all the keys of an evaluation written before it had one)."""
    try:
        with path.open("rb") as handle:
            head = handle.read(4096)
        if path.suffix == ".html":
            return _OWN_HTML in head
        if path.suffix == ".md":
            return _OWN_MARKDOWN.match(head.decode("utf-8", "replace")) is not None
        if path.suffix == ".json":
            document = parse_json(path.read_bytes(), source=str(path))
            return isinstance(document, dict) and (
                document.get("format") == EVALUATION_FORMAT
                or ("format" not in document and any(document.keys() >= keys for keys in _EARLIER_JSON_KEYS))
            )
    except (OSError, ValueError, DataError):
        return False
    return False


def check_own_files(paths: Iterable[Path]) -> None:
    """Refuse to replace a file that is there but was not written by this project (a user's own
    `report.html` or `evaluation.json` in `--out`): OutputError naming it, before any work."""
    for given in map(Path, paths):
        # where the write lands once the folders are made: a `..` after a folder not made yet counts
        path = Path(os.path.realpath(given.parent)) / given.name
        if path.is_dir() or ((path.exists() or path.is_symlink()) and not _written_here(path)):
            raise OutputError(
                f"{given} exists and was not written by robofailring; refusing to replace it: move it away "
                "or choose another --out"
            )


def unique_names(names: Sequence[str]) -> list[str]:
    """`names` made unique in order (`pixels`, `pixels-2`, …): two encoders of one slug (a model with two
    checkpoints) get two folders and two entity paths, never one written over the other."""
    seen: dict[str, int] = {}
    unique = []
    for name in names:
        seen[name] = seen.get(name, 0) + 1
        unique.append(name if seen[name] == 1 else f"{name}-{seen[name]}")
    return unique
