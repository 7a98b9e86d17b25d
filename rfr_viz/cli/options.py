"""The options of the recording verbs that the library's verbs do not have, each declared once.

The options shared with the library's verbs are in `robofailring.cli.options`.
"""

from __future__ import annotations

from typing import Annotated

import typer

from rfr_viz.codecs import AUTO_AV1_PIXELS, CameraCodec

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
