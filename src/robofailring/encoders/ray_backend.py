"""Frames decoded and encoded on a Ray cluster with Ray Data (`--ray ADDRESS`, docs/ray.md).

One pass per `CachedEncoder.prefetch`: the frames become a Ray dataset (`ray.data.from_items`, one
row per frame: its position and the pickled `Frame`, a path or a video frame, never its pixels),
`map_batches` runs them through a pool of actors that each load the encoder once (`load_encoder`
of the job's spec) and decode and encode a batch per call, and the driver streams the embeddings
back (`iter_batches`) into the embedding cache. Ray schedules, retries and applies back-pressure;
nothing here decides which node does what. The workers need robofailring installed and the data
at the same paths (a shared file system).
"""

from __future__ import annotations

import logging
import pickle
import socket
from collections.abc import Iterator, Sequence
from typing import Final
from urllib.parse import urlsplit

import numpy as np

from robofailring.data.model import Frame
from robofailring.encoders.backend import BATCH_FRAMES
from robofailring.errors import ClusterError, RoboFailRingError
from robofailring.extras import needs_extra, require

PROBE_SECONDS: Final[float] = 5.0  # how long a cluster address may take to accept a connection
MAX_BLOCKS: Final[int] = 1000  # the most blocks the frames are split into
LOCAL_ADDRESSES: Final[frozenset[str]] = frozenset({"auto", "local"})


class RayBackend:
    """Encodes on the Ray cluster at `address` (`auto`: the running one, `local`: a new one in this
    machine, `host:port` or `ray://host:port`), with actors running `load_encoder(spec, device)`."""

    ahead = True

    def __init__(
        self,
        address: str,
        *,
        spec: str,
        identity: str,
        device: str | None = None,
        batch_size: int = BATCH_FRAMES,
    ) -> None:
        require("ray")  # before any work: a missing extra is one sentence, not a failure mid-build
        if not address.strip():
            raise ClusterError("--ray needs a cluster address: auto, local, host:port or ray://host:port")
        self.address = address.strip()
        self.spec = spec
        self.identity = identity  # the driver's encoder's: a worker loading other weights is an error
        self.device = device
        self.batch_size = batch_size
        connect(self.address)  # an unreachable cluster fails the job before any frame is read

    def describe(self) -> str:
        return f"Ray ({self.address})"

    def encode_all(self, frames: Sequence[Frame]) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        if not frames:
            return
        with needs_extra("ray"):
            import ray
            import ray.data

        gpus = ray.cluster_resources().get("GPU", 0) if self.device != "cpu" else 0
        workers = int(gpus or ray.cluster_resources().get("CPU", 1))
        items = [{"position": position, "frame": _sendable(frame)} for position, frame in enumerate(frames)]
        blocks = min(-(-len(items) // self.batch_size), MAX_BLOCKS)  # a batch per block: all workers busy
        dataset = ray.data.from_items(items, override_num_blocks=blocks)
        encoded = dataset.map_batches(
            FrameEncoder,
            fn_constructor_kwargs={
                "spec": self.spec,
                "device": self.device if gpus else "cpu",
                "identity": self.identity,
            },
            batch_size=self.batch_size,
            batch_format="numpy",
            compute=ray.data.ActorPoolStrategy(min_size=1, max_size=max(1, workers)),  # one per CPU (or GPU)
            num_gpus=1 if gpus else 0,
            num_cpus=0 if gpus else 1,
        )
        try:
            for batch in encoded.iter_batches(batch_size=None, batch_format="numpy"):
                failed = next((data for data in batch["error"] if data), None)
                if failed is not None:
                    raise pickle.loads(failed)
                yield np.asarray(batch["position"]), np.asarray(batch["embedding"], dtype=np.float32)
        except RoboFailRingError:
            raise
        except Exception as error:
            raise _cause(error, self.address) from error


class FrameEncoder:
    """A Ray Data actor: the encoder loaded once, then a batch of frames decoded and encoded per call."""

    def __init__(self, spec: str, device: str | None, identity: str) -> None:
        from robofailring.encoders import load_encoder

        self.encoder = load_encoder(spec, device=device)
        if self.encoder.identity != identity:
            raise ClusterError(
                f"a Ray worker loaded encoder {spec} as {self.encoder.identity}, not {identity} as this "
                "machine did: give the workers the same weights at the same path"
            )

    def __call__(self, batch: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The batch's embeddings; a frame at fault (undecodable, unreadable) is returned as its error,
        pickled, for the driver to raise as it is (Ray would keep only its text)."""
        positions = np.asarray(batch["position"], dtype=np.int64)
        frames: list[Frame] = [pickle.loads(data) for data in batch["frame"]]
        try:
            embeddings = np.asarray(self.encoder.encode([frame.load() for frame in frames]), np.float32)
        except RoboFailRingError as error:
            embeddings = np.zeros((len(frames), self.encoder.dim), np.float32)
            return {"position": positions, "embedding": embeddings, "error": _errors(len(frames), error)}
        return {"position": positions, "embedding": embeddings, "error": _errors(len(frames))}


def _errors(count: int, error: RoboFailRingError | None = None) -> np.ndarray:
    column = np.empty(count, dtype=object)
    column[:] = [b""] * count
    if error is not None:
        column[0] = pickle.dumps(error)
    return column


def connect(address: str) -> None:
    """Join the Ray cluster at `address` (a process already connected keeps its connection);
    ClusterError naming the address when it cannot be reached."""
    with needs_extra("ray"):
        import ray
        import ray.data

    if not ray.is_initialized():
        if address not in LOCAL_ADDRESSES:
            _probe(address)
        try:
            ray.init(
                address=address,
                include_dashboard=False,
                logging_level=logging.WARNING,
                log_to_driver=False,
            )
        except (ConnectionError, RuntimeError, ValueError) as error:
            raise ClusterError(f"cannot join the Ray cluster at --ray {address}: {error}") from error
    ray.data.DataContext.get_current().enable_progress_bars = False  # the job's own bar counts frames
    logging.getLogger("ray.data").setLevel(logging.WARNING)


def _probe(address: str) -> None:
    """Fail in seconds, not Ray's minutes of retries, when nothing listens at `host:port`."""
    parsed = urlsplit(address if "://" in address else f"ray://{address}")
    try:
        host, port = parsed.hostname, parsed.port
    except ValueError:  # a port that is not a number
        host, port = None, None
    if not host or port is None:
        raise ClusterError(
            f"--ray {address} is not a cluster address: give auto, local, host:port or ray://host:port"
        )
    try:
        with socket.create_connection((host, port), timeout=PROBE_SECONDS):
            pass
    except OSError as error:
        raise ClusterError(
            f"cannot reach the Ray cluster at --ray {address} ({error.strerror or error}); start it "
            "(`ray start --head`) or give the address its head node prints"
        ) from error


def _sendable(frame: Frame) -> bytes:
    """The frame pickled for a worker (where it lives, not its pixels); ClusterError when it cannot go."""
    try:
        return pickle.dumps(frame)
    except (pickle.PicklingError, TypeError, AttributeError) as error:
        raise ClusterError(
            f"frame {frame.reference} cannot be sent to a Ray worker ({error}); encode this dataset without --ray"
        ) from error


def _cause(error: BaseException, address: str) -> ClusterError:
    """A ClusterError for a failed pass, saying in one line what failed a worker (Ray keeps its text)."""
    lines = [line.strip() for line in str(error).splitlines() if line.strip()]
    said = next((line for line in reversed(lines) if line.startswith("robofailring.errors.")), None)
    reason = said.partition(": ")[2] if said else (lines[-1] if lines else type(error).__name__)
    return ClusterError(f"encoding on the Ray cluster at --ray {address} failed: {reason}")
