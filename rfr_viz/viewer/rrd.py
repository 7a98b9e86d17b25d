"""A recording file read back: verified by the viewer's `rrd verify`, its properties and its focus frame, and
whether this project wrote it (the one check before a recording is written over a file)."""

from __future__ import annotations

import os
import subprocess
import tempfile
import warnings
from pathlib import Path
from typing import Any, Final

from rfr_viz.paths import APPLICATION_ID, EVALUATION_APPLICATION_ID, PROPERTIES
from rfr_viz.viewer.binary import viewer_binary, viewer_environment
from robofailring.errors import OutputError
from robofailring.extras import needs_extra
from robofailring.outputs import is_recording

NO_FOOTER: Final[str] = "RRD file has no footer"  # what RrdReader warns on a saved live recording
NO_FOOTER_VERIFY: Final[str] = "Missing RRD footer"  # what `rerun rrd verify` says of one
# the application ids every recording of this project is made under, since its first version
OWN_APPLICATION_IDS: Final[frozenset[str]] = frozenset({APPLICATION_ID, EVALUATION_APPLICATION_ID})


def verify_recording(recording: Path) -> None:
    """`rerun rrd verify`: the only rrd subcommand that fails on a corrupt file (raises ValueError).

    A footer (Rerun's index of the chunks) is required, except in a recording that says it is a saved
    live session (`live` in its properties): those are written without one on purpose (recordings.live).
    A file cut short loses its footer, so any other recording without one is refused."""
    result = _rrd_verify(recording, check_footers=True)
    if result.returncode != 0 and NO_FOOTER_VERIFY in (result.stderr + result.stdout):
        try:
            live = recording_properties(recording).get("live") is True
        except Exception:  # unreadable properties (any reader error): the file is refused below
            live = False
        if live:
            result = _rrd_verify(recording, check_footers=False)
    if result.returncode != 0:
        raise ValueError(f"{recording} is not a valid recording: {(result.stderr or result.stdout).strip()}")


def _rrd_verify(recording: Path, *, check_footers: bool) -> subprocess.CompletedProcess[str]:
    with tempfile.TemporaryDirectory(prefix="rfr-viewer-") as runtime_dir:
        os.chmod(runtime_dir, 0o700)
        return subprocess.run(
            [
                str(viewer_binary()),
                "rrd",
                "verify",
                "--check-footers",
                str(check_footers).lower(),
                str(recording),
            ],
            env=viewer_environment(runtime_dir),
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )


def recording_properties(recording: Path, group: str = PROPERTIES) -> dict[str, Any]:
    """A recording's property group (task, label, t_det, focus_frame, …) read back from the file."""
    with needs_extra("viz"):
        from rerun.chunk import RrdReader

    with warnings.catch_warnings():  # a saved live recording has no footer on purpose (recordings.live)
        warnings.filterwarnings("ignore", message=NO_FOOTER)
        reader = RrdReader(Path(recording))
    chunks = reader.stream().filter(content=f"/__properties/{group}").to_chunks()
    for chunk in chunks:
        columns = chunk.to_record_batch().to_pydict()
        return {name: values[0][0] for name, values in columns.items() if not name.startswith("rerun.")}
    return {}


def focus_frame(recording: Path) -> int:
    """The frame a reviewer wants first: the recorded focus (an alarm, a miss's peak), else t_det, else 0."""
    found = recording_properties(recording)
    for key in ("focus_frame", "t_det"):
        value = found.get(key)
        if isinstance(value, int) and value >= 0:
            return value
    return 0


def written_here(recording: Path) -> bool:
    """Whether `recording` is a Rerun recording this project wrote: each of its recordings made under one
    of the project's application ids (a user's own `.rrd`, whatever its name, is not)."""
    if not is_recording(recording):
        return False
    with needs_extra("viz"):
        from rerun.chunk import RrdReader

    try:
        with warnings.catch_warnings():  # a saved live recording has no footer on purpose (recordings.live)
            warnings.filterwarnings("ignore", message=NO_FOOTER)
            stores = RrdReader(Path(recording)).recordings()
    except Exception:  # any reader error: a file that cannot be read whole is not taken for ours
        return False
    return bool(stores) and all(store.application_id in OWN_APPLICATION_IDS for store in stores)


def check_recording_file(path: Path) -> None:
    """Refuse, before any work, to write a recording over anything but a recording this project wrote (a
    folder, a file of another kind, a user's own Rerun recording): OutputError naming it."""
    path = Path(path)
    if path.is_dir() or (path.exists() and not written_here(path)):
        raise OutputError(
            f"{path} exists and is not a Rerun recording written by robofailring; refusing to write over it: "
            "move it away or choose another output"
        )
