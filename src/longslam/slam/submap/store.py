"""Finished submaps' TSDFs on disk, a few of the most recently used held in memory.

A finished submap's compacted TSDF (about 1.2 MB with the paper's voxels) is needed again only
when a newer submap overlaps it (registration) and once more at the end (the global map's
fusion). Held in memory they would be the submap method's growth with the route. Here they go
into one SQLite file as they finish (raw bytes: they are read
back far more often than written, and int8 distances hardly pay for deflating) and come back on
demand through a small least-recently-used cache.

The file is scratch: it lives beside the run's other files (or in a temporary folder) and is
removed when the store is closed.
"""

from __future__ import annotations

import contextlib
import shutil
import sqlite3
import tempfile
from collections import OrderedDict
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from longslam.core.errors import InputError
from longslam.slam.submap.tsdf import BLOCK_VOXELS, TSDF

FILE_NAME = "submaps.db"

_SCHEMA = """
CREATE TABLE IF NOT EXISTS Submap (
    id INTEGER PRIMARY KEY,
    blocks INTEGER NOT NULL,
    keys BLOB NOT NULL,     -- int64 block keys
    sdf BLOB NOT NULL,      -- int8 distances, BLOCK_VOXELS per block
    weight BLOB NOT NULL    -- float16 weights, BLOCK_VOXELS per block
);
"""


class SubmapStore:
    """Compacted TSDFs by submap index: `put` when a submap finishes, `get` when it is needed."""

    def __init__(self, voxel: float, truncation: float, in_memory: int, folder: str | Path | None = None):
        self.voxel = float(voxel)
        self.truncation = float(truncation)
        self.in_memory = int(in_memory)
        self._own_dir = None
        if folder is None:
            self._own_dir = folder = tempfile.mkdtemp(prefix="longslam-submaps-")
        self.path = Path(folder) / FILE_NAME
        self.path.unlink(missing_ok=True)  # a run cut short left its scratch behind
        try:
            self._db = sqlite3.connect(self.path)
            # Scratch that no other process reads and nobody reopens: no journal, no fsync.
            self._db.execute("PRAGMA journal_mode=OFF")
            self._db.execute("PRAGMA synchronous=OFF")
            self._db.executescript(_SCHEMA)
        except sqlite3.Error as err:
            raise InputError(f"{self.path} cannot be written: {err}") from None
        self._cache: OrderedDict[int, TSDF] = OrderedDict()
        self._stored_bytes = 0
        self.reads = 0  # TSDFs read back from disk (not found in the cache)

    @contextlib.contextmanager
    def _sqlite(self) -> Iterator[None]:
        try:
            with self._db:
                yield
        except sqlite3.Error as err:  # a full disk, a size limit
            raise InputError(f"{self.path} cannot be written: {err}") from None

    def put(self, index: int, tsdf: TSDF) -> None:
        """Store a compacted TSDF under `index`; it stays in the cache as the most recent."""
        arrays = tsdf.compacted_arrays()
        with self._sqlite():
            self._db.execute(
                "INSERT OR REPLACE INTO Submap VALUES (?, ?, ?, ?, ?)",
                (
                    int(index),
                    len(arrays["keys"]),
                    *(np.ascontiguousarray(arrays[k]).tobytes() for k in ("keys", "sdf", "weight")),
                ),
            )
        self._stored_bytes += sum(a.nbytes for a in arrays.values())
        self._remember(int(index), tsdf)

    def get(self, index: int, cache: bool = True) -> TSDF:
        """The TSDF stored under `index`, from the cache or read back (and then cached, unless
        `cache` is False: the global map's fusion reads each one once)."""
        index = int(index)
        if index in self._cache:
            self._cache.move_to_end(index)
            return self._cache[index]
        with self._sqlite():
            row = self._db.execute("SELECT blocks, keys, sdf, weight FROM Submap WHERE id=?", (index,)).fetchone()
        if row is None:
            raise KeyError(f"{self.path}: no submap {index}")
        blocks, keys, sdf, weight = row
        self.reads += 1
        tsdf = TSDF.from_compacted_arrays(
            self.voxel,
            self.truncation,
            np.frombuffer(keys, np.int64).copy(),
            np.frombuffer(sdf, np.int8).reshape(blocks, BLOCK_VOXELS).copy(),
            np.frombuffer(weight, np.float16).reshape(blocks, BLOCK_VOXELS).copy(),
        )
        if cache:
            self._remember(index, tsdf)
        return tsdf

    def _remember(self, index: int, tsdf: TSDF) -> None:
        self._cache[index] = tsdf
        self._cache.move_to_end(index)
        while len(self._cache) > self.in_memory:
            self._cache.popitem(last=False)

    def drop_cache(self) -> None:
        self._cache.clear()

    @property
    def cached_bytes(self) -> int:
        return int(sum(t.nbytes for t in self._cache.values()))

    @property
    def stored_bytes(self) -> int:
        """Bytes of voxel arrays and keys put on disk."""
        return self._stored_bytes

    def close(self) -> None:
        """Close and remove the scratch file (and the temporary folder made for it)."""
        self._cache.clear()
        self._db.close()
        self.path.unlink(missing_ok=True)
        if self._own_dir is not None:
            shutil.rmtree(self._own_dir, ignore_errors=True)
