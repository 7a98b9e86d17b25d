"""The encoder walk (issue 53): the project files opening `timm:<model>:<checkpoint>@onnx-int8` passes through.

It opens the encoder the way the CLI does, `open_encoder(spec, cache_dir=…)` (`EncoderPlacement.open`), on
a tiny randomly initialised timm model (`test_efficientnet`) whose checkpoint it writes to a temporary folder, its
int8 export made first (by an open the walk does not count, its memo then cleared: a second process opening the
export it finds); then encodes one frame. `sys.setprofile` records every Python function entered in a project
file (`src/robofailring` and `rfr_viz` of the checkout imported) meanwhile, in the order they begin:

- the walk is what `open_encoder` calls, down to the `CachedEncoder` it returns (the encoder's construction): every
  project function entered below it (its own entry is where the walk starts, not a stay), a module's body run by
  an import on the way and a generator resumed not counted;
- a stay is a maximal run of consecutive entries in the same file;
- files are the distinct files of the walk, returns the stays in a file the walk has been in before: stays =
  files + returns, so a walk that never comes back to a file has as many stays as files.

Encoding the frame is a second walk, counted the same way from `encode_images`. Counts, not times: they do not
depend on the machine. `--checkout DIR` measures another checkout's library (DIR/src), e.g. an older commit's.

Run: .venv/bin/python -m bench.encoder_walk [--show-calls] [--checkout DIR]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from types import FrameType
from typing import Any

from bench._timing import print_machine

MODEL = "test_efficientnet"  # timm's own tiny EfficientNet: random weights, exported in seconds
RUNTIME = "onnx-int8"


@dataclass
class Walk:
    """The project functions entered while it records: (file, function) in the order they began."""

    roots: tuple[Path, ...]
    entries: list[tuple[str, str]] = field(default_factory=list)
    _started: set[int] = field(default_factory=set)

    def _profile(self, frame: FrameType, event: str, _arg: Any) -> None:
        code = frame.f_code
        if event != "call":
            return
        if code.co_name == "<module>" or id(frame) in self._started:  # an import's body, a generator resumed
            return
        path = Path(code.co_filename)
        root = next((root for root in self.roots if path.is_relative_to(root)), None)
        if root is None:
            return
        self._started.add(id(frame))  # frames are kept alive by the set: an id is never reused meanwhile
        self._frames.append(frame)
        self.entries.append((str(path.relative_to(root.parent)), code.co_qualname))

    def record(self, run: Callable[[], Any]) -> Any:
        self._frames: list[FrameType] = []
        sys.setprofile(self._profile)
        try:
            return run()
        finally:
            sys.setprofile(None)
            self._frames.clear()

    def stays(self) -> list[str]:
        """The file of each stay, in order: of the functions the first one entered calls."""
        files: list[str] = []
        for file, _ in self.entries[1:]:
            if not files or files[-1] != file:
                files.append(file)
        return files


def report(title: str, walk: Walk, *, show_calls: bool) -> None:
    stays = walk.stays()
    files = list(dict.fromkeys(stays))
    print(f"\n{title}: {len(stays)} stays through {len(files)} files, {len(stays) - len(files)} returns")
    print(f"  {len(walk.entries)} function entries")
    if show_calls:
        for file, function in walk.entries:
            print(f"    {file}: {function}")
    for number, file in enumerate(stays, 1):
        again = " (again)" if file in stays[: number - 1] else ""
        print(f"  {number:2}. {file}{again}")


def project_roots() -> tuple[Path, ...]:
    """`src/robofailring` and `rfr_viz` of the checkout whose `robofailring` is imported."""
    import robofailring

    package = Path(robofailring.__file__).resolve().parent
    checkout = package.parents[1]
    return tuple(root for root in (package, checkout / "rfr_viz") if root.is_dir())


def write_checkpoint(folder: Path) -> Path:
    """A state_dict of `MODEL` with random weights (seed 0)."""
    import timm
    import torch

    torch.manual_seed(0)
    network = timm.create_model(MODEL, pretrained=False, num_classes=0)
    path = folder / f"{MODEL}.pth"
    torch.save(network.state_dict(), path)
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--show-calls", action="store_true", help="list every function entered, not only the stays"
    )
    parser.add_argument(
        "--checkout", type=Path, help="measure the library in DIR/src (default: this checkout's)"
    )
    args = parser.parse_args()
    if args.checkout is not None:
        sys.path.insert(0, str(args.checkout.resolve() / "src"))
    print_machine(libraries=("torch", "timm", "onnxruntime"))
    import numpy as np

    import robofailring.encoders as encoders

    roots = project_roots()
    print(f"project files under: {', '.join(str(root) for root in roots)}")
    with tempfile.TemporaryDirectory() as tmp:
        checkpoint = write_checkpoint(Path(tmp))
        spec = f"timm:{MODEL}:{checkpoint}@{RUNTIME}"
        print(f"spec: timm:{MODEL}:<temporary folder>/{checkpoint.name}@{RUNTIME}")
        encoders.open_encoder(spec, cache_dir=Path(tmp) / "cache")  # makes the export
        encoders._loaded_encoder.cache_clear()
        opening = Walk(roots)
        opened = opening.record(lambda: encoders.open_encoder(spec, cache_dir=Path(tmp) / "cache"))
        encoding = Walk(roots)
        frame = np.random.default_rng(0).integers(0, 256, (64, 64, 3), dtype=np.uint8)
        embedding = encoding.record(lambda: opened.encode_images([frame]))
    print(
        f"opened {opened.identity} ({type(opened.encoder).__name__}), one frame to {embedding.shape[1]} numbers"
    )
    report("opening (the walk)", opening, show_calls=args.show_calls)
    report("encoding one frame", encoding, show_calls=args.show_calls)


if __name__ == "__main__":
    main()
