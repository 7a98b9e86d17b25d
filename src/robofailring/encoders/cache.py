"""On-disk embedding cache keyed by (encoder identity, image content)."""

from __future__ import annotations

import hashlib
import os
import sqlite3
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from robofailring.data.model import Frame
from robofailring.encoders.base import Encoder


def default_cache_dir() -> Path:
    """`$ROBOFAILRING_CACHE` or `~/.cache/robofailring`."""
    env = os.environ.get("ROBOFAILRING_CACHE")
    return Path(env).expanduser() if env else Path.home() / ".cache" / "robofailring"


class EmbeddingCache:
    """A SQLite file per encoder identity mapping an image digest to its embedding."""

    def __init__(self, identity: str, dim: int, *, root: Path | None = None) -> None:
        self.identity = identity
        self.dim = dim
        root = Path(root) if root is not None else default_cache_dir()
        root.mkdir(parents=True, exist_ok=True)
        name = hashlib.blake2b(identity.encode(), digest_size=8).hexdigest()
        self.path = root / f"embeddings-{name}.sqlite"
        self._db = sqlite3.connect(self.path, timeout=60)
        self._db.execute("PRAGMA journal_mode=WAL")
        self._db.execute("CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT)")
        self._db.execute("CREATE TABLE IF NOT EXISTS emb (digest TEXT PRIMARY KEY, vec BLOB)")
        self._db.execute(
            "CREATE TABLE IF NOT EXISTS files (path TEXT PRIMARY KEY, size INTEGER, mtime_ns INTEGER, digest TEXT)"
        )
        self._db.execute("INSERT OR IGNORE INTO meta VALUES ('identity', ?)", (identity,))
        self._db.commit()

    def digests(self, frames: Sequence[Frame]) -> list[str]:
        """Content digests of frames; an unchanged file (same size and mtime) is not read again."""
        keys: list[str | None] = [None] * len(frames)
        signatures: dict[str, tuple[int, int]] = {}
        for i, frame in enumerate(frames):
            if frame.path is None:
                keys[i] = frame.content_key()
                continue
            try:
                stat = frame.path.stat()
            except OSError:
                keys[i] = frame.content_key()  # raises DataError naming the file
                continue
            signatures[str(frame.path)] = (stat.st_size, stat.st_mtime_ns)
        known: dict[str, str] = {}
        paths = list(signatures)
        for start in range(0, len(paths), 500):
            chunk = paths[start : start + 500]
            marks = ",".join("?" * len(chunk))
            rows = self._db.execute(
                f"SELECT path, size, mtime_ns, digest FROM files WHERE path IN ({marks})", chunk
            )
            for path, size, mtime_ns, digest in rows:
                if signatures[path] == (size, mtime_ns):
                    known[path] = digest
        fresh = []
        for i, frame in enumerate(frames):
            if keys[i] is None:
                path = str(frame.path)
                if path not in known:
                    known[path] = frame.content_key()
                    fresh.append((path, *signatures[path], known[path]))
                keys[i] = known[path]
        if fresh:
            with self._db:
                self._db.executemany("INSERT OR REPLACE INTO files VALUES (?, ?, ?, ?)", fresh)
        return [key for key in keys if key is not None]

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


class CachedEncoder:
    """Encodes frames through an encoder, reusing cached embeddings by image content."""

    def __init__(self, encoder: Encoder, *, cache_dir: Path | None = None, enabled: bool = True) -> None:
        self.encoder = encoder
        self.cache = EmbeddingCache(encoder.identity, encoder.dim, root=cache_dir) if enabled else None
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
        if self.cache is None:
            self.misses += len(frames)
            chunks = [
                self.encoder.encode([frame.load() for frame in frames[start : start + batch_size]])
                for start in range(0, len(frames), batch_size)
            ]
            return np.concatenate(chunks).astype(np.float32, copy=False)
        digests = self.cache.digests(frames)
        found = self.cache.get_many(digests)
        missing = [i for i, digest in enumerate(digests) if digest not in found]
        self.hits += len(frames) - len(missing)
        self.misses += len(missing)
        fresh: dict[str, np.ndarray] = {}
        for start in range(0, len(missing), batch_size):
            chunk = [i for i in missing[start : start + batch_size] if digests[i] not in fresh]
            if not chunk:
                continue
            vectors = self.encoder.encode([frames[i].load() for i in chunk])
            for i, vector in zip(chunk, vectors, strict=True):
                fresh[digests[i]] = vector
            self.cache.put_many({digests[i]: fresh[digests[i]] for i in chunk})
        found.update(fresh)
        return np.stack([found[digest] for digest in digests]).astype(np.float32, copy=False)

    def encode_images(self, images: Sequence[np.ndarray]) -> np.ndarray:
        """Encode in-memory images (through the cache as well)."""
        return self.encode_frames([Frame.from_array(image) for image in images])
