"""On-disk embedding cache keyed by (encoder identity, image content)."""

from __future__ import annotations

import contextlib
import hashlib
import logging
import os
import sqlite3
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from robofailring.data.model import Frame
from robofailring.encoders.backend import EncodingBackend, LocalBackend
from robofailring.encoders.base import Encoder
from robofailring.progress import progress_bar


def default_cache_dir() -> Path:
    """`$ROBOFAILRING_CACHE` or `~/.cache/robofailring`."""
    env = os.environ.get("ROBOFAILRING_CACHE")
    return Path(env).expanduser() if env else Path.home() / ".cache" / "robofailring"


def cache_identity(encoder: Encoder) -> str:
    """The key of an encoder's embedding cache: its identity, plus its runtime when that is not torch
    (an ONNX export's numbers differ from torch's in the last digits, int8's by up to 1 % in cosine)."""
    runtime = getattr(encoder, "runtime", "torch")
    return encoder.identity if runtime == "torch" else f"{encoder.identity}@{runtime}"


_log = logging.getLogger("robofailring")
_WARNED: set[str] = set()


def _warn_once(message: str) -> None:
    if message not in _WARNED:
        _WARNED.add(message)
        _log.warning("warning: %s", message)


class EmbeddingCache:
    """A SQLite file per encoder identity mapping an image's content digest to its embedding.

    The key is a digest of the image file's bytes, read every time: a file rewritten with the
    same size and modification time is still seen as new (`bench/bench_cache.py` measures what
    hashing costs against decoding).
    """

    def __init__(self, identity: str, dim: int, *, root: Path | None = None) -> None:
        self.identity = identity
        self.dim = dim
        root = Path(root) if root is not None else default_cache_dir()
        name = hashlib.blake2b(identity.encode(), digest_size=8).hexdigest()
        self.path = root / f"embeddings-{name}.sqlite"
        root.mkdir(parents=True, exist_ok=True)
        self._db = sqlite3.connect(self.path, timeout=60)
        try:
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute("CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT)")
            self._db.execute("CREATE TABLE IF NOT EXISTS emb (digest TEXT PRIMARY KEY, vec BLOB)")
            self._db.execute("INSERT OR IGNORE INTO meta VALUES ('identity', ?)", (identity,))
            self._db.commit()
        except sqlite3.Error:
            self._db.close()
            raise

    @classmethod
    def open(cls, identity: str, dim: int, *, root: Path | None = None) -> EmbeddingCache | None:
        """The cache, rebuilt if its file is corrupt; None (with one warning) where it cannot be used.

        The cache is disposable: nothing is lost by rebuilding it or running without it.
        """
        where = Path(root) if root is not None else default_cache_dir()
        try:
            return cls(identity, dim, root=root)
        except sqlite3.DatabaseError as error:
            if isinstance(error, sqlite3.OperationalError):
                _warn_once(f"cannot use the embedding cache in {where} ({error}); running without it")
                return None
            name = hashlib.blake2b(identity.encode(), digest_size=8).hexdigest()
            path = where / f"embeddings-{name}.sqlite"
            _warn_once(f"the embedding cache {path} is corrupt ({error}); rebuilding it")
            for stale in (path, path.with_name(path.name + "-wal"), path.with_name(path.name + "-shm")):
                with contextlib.suppress(OSError):
                    stale.unlink()
        except OSError as error:
            problem = (
                "it is a file" if where.exists() and not where.is_dir() else error.strerror or str(error)
            )
            _warn_once(f"cannot use the embedding cache folder {where} ({problem}); running without it")
            return None
        try:
            return cls(identity, dim, root=root)
        except (sqlite3.Error, OSError) as error:
            _warn_once(f"cannot rebuild the embedding cache in {where} ({error}); running without it")
            return None

    def digests(self, frames: Sequence[Frame]) -> list[str]:
        """Content digests of the frames (of the file bytes, or of an in-memory array)."""
        return [frame.content_key() for frame in frames]

    def get_many(self, digests: Sequence[str]) -> dict[str, np.ndarray]:
        found: dict[str, np.ndarray] = {}
        unique = list(dict.fromkeys(digests))
        for start in range(0, len(unique), 500):
            chunk = unique[start : start + 500]
            marks = ",".join("?" * len(chunk))
            rows = self._db.execute(f"SELECT digest, vec FROM emb WHERE digest IN ({marks})", chunk)
            for digest, blob in rows:
                vector = np.frombuffer(blob, dtype=np.float32)
                if vector.shape == (self.dim,):
                    found[digest] = vector
        return found

    def put_many(self, items: dict[str, np.ndarray]) -> None:
        rows = [(digest, np.asarray(vec, dtype=np.float32).tobytes()) for digest, vec in items.items()]
        with self._db:
            self._db.executemany("INSERT OR REPLACE INTO emb VALUES (?, ?)", rows)

    def close(self) -> None:
        self._db.close()


class HeldEmbeddings:
    """Embeddings held in memory by content digest: where a backend encoding ahead puts its results
    when there is no embedding cache to write them to (`CachedEncoder.prefetch`)."""

    def __init__(self, dim: int) -> None:
        self.dim = dim
        self.path = Path("<memory>")
        self._held: dict[str, np.ndarray] = {}

    def digests(self, frames: Sequence[Frame]) -> list[str]:
        return [frame.content_key() for frame in frames]

    def get_many(self, digests: Sequence[str]) -> dict[str, np.ndarray]:
        return {digest: self._held[digest] for digest in digests if digest in self._held}

    def put_many(self, items: dict[str, np.ndarray]) -> None:
        self._held.update({digest: np.asarray(vec, dtype=np.float32) for digest, vec in items.items()})


class CachedEncoder:
    """Encodes frames through an encoder, reusing cached embeddings by image content.

    Cache misses are encoded here, on demand; `backend` (robofailring.encoders.backend) is where
    `prefetch` encodes, ahead of the job, the frames a job will need (a Ray cluster), or nothing.
    """

    def __init__(
        self,
        encoder: Encoder,
        *,
        cache_dir: Path | None = None,
        enabled: bool = True,
        backend: EncodingBackend | None = None,
    ) -> None:
        self.encoder = encoder
        self.cache: EmbeddingCache | HeldEmbeddings | None = (
            EmbeddingCache.open(cache_identity(encoder), encoder.dim, root=cache_dir) if enabled else None
        )
        self.backend: EncodingBackend = backend if backend is not None else LocalBackend(encoder)
        self.hits = 0
        self.misses = 0

    @property
    def identity(self) -> str:
        return self.encoder.identity

    @property
    def dim(self) -> int:
        return self.encoder.dim

    def encode_frames(self, frames: Sequence[Frame], *, batch_size: int = 64) -> np.ndarray:
        """(N, dim) unit embeddings of the frames, decoding and encoding only cache misses."""
        if not frames:
            return np.zeros((0, self.dim), dtype=np.float32)
        if self.cache is not None:
            try:
                return self._encode_cached(frames, self.cache, batch_size=batch_size)
            except sqlite3.Error as error:  # a full disk, a file made read-only or corrupted mid-run
                _warn_once(f"the embedding cache {self.cache.path} failed ({error}); running without it")
                self.cache = None
        self.misses += len(frames)
        local = LocalBackend(self.encoder, batch_size=batch_size)
        return np.concatenate([vectors for _, vectors in local.encode_all(frames)])

    def prefetch(self, frames: Iterable[Frame]) -> None:
        """Encode, through the backend and ahead of the job, every frame of `frames` the cache lacks
        (each distinct image once), into the cache; a no-op for a backend that encodes on demand, which
        leaves `frames` (a generator, say) unread.

        Without a usable cache the embeddings are held in memory for this encoder's later calls.
        """
        if not self.backend.ahead:
            return
        frames = list(frames)
        if not frames:
            return
        if self.cache is None:
            self.cache = HeldEmbeddings(self.dim)
        digests = self.cache.digests(frames)
        found = self.cache.get_many(digests)
        todo = {digest: frame for digest, frame in zip(digests, frames, strict=True) if digest not in found}
        keys, missing = list(todo), list(todo.values())
        if not missing:
            return
        with progress_bar(
            total=len(missing), desc=f"encoding on {self.backend.describe()}", unit="frame"
        ) as bar:
            for positions, vectors in self.backend.encode_all(missing):
                self.cache.put_many(
                    {keys[int(p)]: vector for p, vector in zip(positions, vectors, strict=True)}
                )
                bar.update(len(positions))
        self.misses += len(missing)

    def _encode_cached(
        self, frames: Sequence[Frame], cache: EmbeddingCache | HeldEmbeddings, *, batch_size: int
    ) -> np.ndarray:
        digests = cache.digests(frames)
        found = cache.get_many(digests)
        todo = {digest: i for i, digest in enumerate(digests) if digest not in found}
        keys = list(todo)
        local = LocalBackend(self.encoder, batch_size=batch_size)
        for positions, vectors in local.encode_all([frames[i] for i in todo.values()]):
            fresh = {keys[int(p)]: vector for p, vector in zip(positions, vectors, strict=True)}
            cache.put_many(fresh)
            found.update(fresh)
        missing = sum(1 for digest in digests if digest in todo)
        self.hits += len(frames) - missing
        self.misses += missing
        return np.stack([found[digest] for digest in digests]).astype(np.float32, copy=False)

    def encode_images(self, images: Sequence[np.ndarray]) -> np.ndarray:
        """Encode in-memory images (through the cache as well)."""
        return self.encode_frames([Frame.from_array(image) for image in images])
