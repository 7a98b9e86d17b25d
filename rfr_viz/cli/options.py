"""The options of the recording verbs that the library's verbs do not have, each declared once, and the
`RECORDINGS` option group (`recordings_options`: which trajectories a replay or comparison records, a
`Recordings`).

The options shared with the library's verbs are in `robofailring.cli.options` and `robofailring.cli.option_groups`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Final

import typer

from rfr_viz.codecs import AUTO_AV1_PIXELS, CameraCodec
from rfr_viz.jobs.recorded import Recordings
from rfr_viz.paths import DEFAULT_OUT
from robofailring.cli.groups import OptionGroup
from robofailring.cli.options import FpsOption, LeaveOneOutOption

CameraCodecOption = Annotated[
    CameraCodec,
    typer.Option(
        "--camera-codec",
        case_sensitive=False,
        help="How camera frames are stored: jpeg images, av1 or h264 video, or auto "
        f"(av1 when a view has ≥ {AUTO_AV1_PIXELS / 1e6:g} Mpx over all its frames, else jpeg). "
        "AV1 plays in the Rerun viewer as is; H.264 needs ffmpeg ≥ 5.1 where it is viewed.",
    ),
]
LiveCameraCodecOption = Annotated[
    CameraCodec,
    typer.Option(
        "--camera-codec",
        case_sensitive=False,
        help="How camera frames are stored: jpeg images, or av1 or h264 video encoded frame by frame; "
        "auto means jpeg live (no frame size is known in advance). "
        "AV1 plays in the Rerun viewer as is; H.264 needs ffmpeg ≥ 5.1 where it is viewed.",
    ),
]
RecordingsOutOption = Annotated[
    Path, typer.Option("--out", help="Folder for the .rrd files (one per trajectory).")
]
TrajectoriesOption = Annotated[
    list[str] | None,
    typer.Option(
        "--trajectory", help="Only this trajectory (`<task>/<episode>` or the episode); repeatable."
    ),
]


def recordings_options(
    out: RecordingsOutOption = DEFAULT_OUT,
    trajectory: TrajectoriesOption = None,
    leave_one_out: LeaveOneOutOption = False,
    fps: FpsOption = None,
    camera_codec: CameraCodecOption = CameraCodec.AUTO,
) -> Recordings:
    """--out, --trajectory, --leave-one-out, --fps and --camera-codec as one `Recordings`."""
    return Recordings(
        out=out,
        trajectories=tuple(trajectory or ()),
        leave_one_out=leave_one_out,
        fps=fps,
        camera_codec=camera_codec,
    )


RECORDINGS: Final[OptionGroup[Recordings]] = OptionGroup(recordings_options, panel="Recordings")
