"""The optional parts of the install (`pip install robofailring[<extra>]`) and the one guard of their imports.

The core install is the library and the verbs that need no extra. Every import of a module that
only an extra installs sits in `with needs_extra("<extra>"):`, so that a missing one ends in one
sentence naming the extra (`MissingExtraError`, exit status 1), never a traceback::

    with needs_extra("viz"):
        import rerun as rr

`EXTRAS` is what each extra of pyproject.toml installs, by the name it is imported with; tests keep
the two in step and check that no such import is left unguarded.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Final

from robofailring.errors import MissingExtraError

#: extra -> {top-level module imported: the distribution that installs it}
EXTRAS: Final[dict[str, dict[str, str]]] = {
    "clip": {
        "torch": "torch",
        "torchvision": "torchvision",
        "open_clip": "open-clip-torch",
        "PIL": "pillow",
    },
    "viz": {
        "rerun": "rerun-sdk",
        "rerun_cli": "rerun-sdk",
        "umap": "umap-learn",
        "scipy": "umap-learn",
        "sklearn": "umap-learn",
        "av": "av",
    },
    "sim": {"pybullet": "pybullet", "pybullet_data": "pybullet", "pybullet_utils": "pybullet"},
    "video": {"av": "av", "pyarrow": "pyarrow"},
    "vlm": {"httpx": "httpx"},
    "hdf5": {"h5py": "h5py"},
    "rosbag": {"rosbags": "rosbags"},
    "notebook": {"rerun": "rerun-sdk", "rerun_notebook": "rerun-notebook"},
    "onnx": {"onnxruntime": "onnxruntime", "onnx": "onnx"},
    "openvino": {"openvino": "openvino"},
    "ray": {"ray": "ray"},
    "gym": {"gymnasium": "gymnasium"},
}

#: What each extra is for, in the error's sentence.
PURPOSES: Final[dict[str, str]] = {
    "clip": "CLIP and trained encoders",
    "viz": "Rerun recordings and the viewer",
    "sim": "the simulated default dataset",
    "video": "video episodes and LeRobot datasets",
    "vlm": "the VLM client",
    "hdf5": "HDF5 datasets",
    "rosbag": "ROS bags",
    "notebook": "the notebook viewer",
    "onnx": "the ONNX Runtime encoders (--runtime onnx, onnx-int8)",
    "openvino": "the OpenVINO int8 encoder (--runtime openvino-int8)",
    "ray": "encoding on a Ray cluster (--ray)",
    "gym": "the rollout monitor (robofailring.monitor)",
}


def missing_extra(extra: str, module: str) -> MissingExtraError:
    """The error for `module`, one of `extra`'s modules, not being installed."""
    top = module.split(".")[0]
    distribution = EXTRAS[extra].get(top, top)
    return MissingExtraError(
        f"{distribution} is not installed; it comes with the {extra} extra ({PURPOSES[extra]}): "
        f'install robofailring[{extra}] (pip install "robofailring[{extra}]")',
        name=top,
        extra=extra,
    )


def require(extra: str) -> None:
    """Raise `MissingExtraError` now, before any work, unless every module of `extra` is installed."""
    for module in EXTRAS[extra]:
        if importlib.util.find_spec(module) is None:
            raise missing_extra(extra, module)


@contextmanager
def needs_extra(extra: str) -> Iterator[None]:
    """Imports inside this block come from `extra`: a module of it not installed is a `MissingExtraError`.

    A missing module that is not `extra`'s (a bug, or a broken install of something else) is left
    as the `ModuleNotFoundError` it is.
    """
    if extra not in EXTRAS:
        raise KeyError(f"unknown extra {extra!r}; the extras are {', '.join(EXTRAS)}")
    try:
        yield
    except MissingExtraError:
        raise
    except ModuleNotFoundError as error:
        top = (error.name or "").split(".")[0]
        if top not in EXTRAS[extra] or importlib.util.find_spec(top) is not None:
            raise  # not the extra's, or a part of an installed one missing: not a missing extra
        raise missing_extra(extra, top) from None
