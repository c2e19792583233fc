"""Long-term memory on disk: a SQLite database of graph nodes, their data and their links.

Modelled on RTAB-Map's database (tables Node, Data, Link, Statistics, Admin): nodes that leave
working memory are written here with their features and local grid, so RAM stays bounded, and
are read back when a loop closure brings their neighbourhood back. Every write is committed at
once in WAL mode, so a run killed mid-way leaves a database that opens with what it had.
"""

from __future__ import annotations

import contextlib
import io
import json
import sqlite3
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from longslam.core.errors import InputError

SCHEMA_VERSION = 1

_SCHEMA = """
CREATE TABLE IF NOT EXISTS Admin (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS Node (
    id INTEGER PRIMARY KEY,
    stamp REAL NOT NULL,
    pose BLOB NOT NULL,          -- 4x4 float64, optimised estimate when last written
    odometry BLOB NOT NULL,      -- 4x4 float64, the odometry pose at the node
    weight INTEGER NOT NULL DEFAULT 0
);
CREATE TABLE IF NOT EXISTS Data (
    id INTEGER PRIMARY KEY REFERENCES Node(id),
    arrays BLOB NOT NULL         -- the node's arrays (features, 3D points, local grid) as one .npz
);
CREATE TABLE IF NOT EXISTS Link (
    from_id INTEGER NOT NULL,
    to_id INTEGER NOT NULL,
    type TEXT NOT NULL,          -- odometry, loop, proximity
    transform BLOB NOT NULL,     -- 4x4 float64: pose of to_id in from_id's frame
    information BLOB NOT NULL,   -- information matrix, float64
    PRIMARY KEY (from_id, to_id, type)
);
CREATE TABLE IF NOT EXISTS Statistics (key TEXT PRIMARY KEY, value TEXT NOT NULL);
"""


def _blob(array: np.ndarray) -> bytes:
    return np.ascontiguousarray(array, dtype=np.float64).tobytes()


def _matrix(blob: bytes, shape: tuple[int, ...]) -> np.ndarray:
    return np.frombuffer(blob, dtype=np.float64).reshape(shape).copy()


@dataclass
class StoredNode:
    id: int
    stamp: float
    pose: np.ndarray
    odometry: np.ndarray
    weight: int
    arrays: dict[str, np.ndarray]


class MemoryDatabase:
    """A node store in one SQLite file. Opening an existing file reads what it holds."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        try:
            self._db = sqlite3.connect(self.path)
            self._db.execute("PRAGMA journal_mode=WAL")
            # Without an fsync per commit (one a node would cost more than the node's own writes).
            # In WAL mode the file still survives the process dying at any point; only a power cut
            # can lose the newest nodes, and a run cut short is run again. RTAB-Map's own default is synchronous OFF.
            self._db.execute("PRAGMA synchronous=NORMAL")
            self._db.executescript(_SCHEMA)
            version = self._db.execute("SELECT value FROM Admin WHERE key='schema_version'").fetchone()
        except sqlite3.OperationalError as err:  # a full disk, a size limit, no permission
            raise InputError(f"{self.path} cannot be written: {err}") from None
        except sqlite3.DatabaseError as err:
            raise InputError(f"{self.path} is not a longslam memory database: {err}") from None
        if version is None:
            with self._writing():
                self._db.execute("INSERT INTO Admin VALUES ('schema_version', ?)", (str(SCHEMA_VERSION),))
        elif int(version[0]) != SCHEMA_VERSION:
            raise InputError(f"{self.path}: schema version {version[0]}, this longslam reads {SCHEMA_VERSION}")

    def close(self) -> None:
        self._db.close()

    @contextlib.contextmanager
    def _writing(self) -> Iterator[None]:
        """One transaction; SQLite's errors name no file, so name this one."""
        try:
            with self._db:
                yield
        except sqlite3.OperationalError as err:
            raise InputError(f"{self.path} cannot be written: {err}") from None

    def __enter__(self) -> "MemoryDatabase":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def put_node(
        self,
        node_id: int,
        stamp: float,
        pose: np.ndarray,
        odometry: np.ndarray,
        arrays: dict[str, np.ndarray],
        weight: int = 0,
    ) -> None:
        buffer = io.BytesIO()
        # Stored as they are: deflating costs milliseconds a node for a file a little smaller on
        # disk; the descriptors hardly compress anyway.
        np.savez(buffer, **arrays)
        with self._writing():
            self._db.execute(
                "INSERT OR REPLACE INTO Node VALUES (?, ?, ?, ?, ?)",
                (node_id, float(stamp), _blob(pose), _blob(odometry), int(weight)),
            )
            self._db.execute("INSERT OR REPLACE INTO Data VALUES (?, ?)", (node_id, buffer.getvalue()))

    def update_poses(self, poses: dict[int, np.ndarray]) -> None:
        with self._writing():
            self._db.executemany("UPDATE Node SET pose=? WHERE id=?", [(_blob(p), int(i)) for i, p in poses.items()])

    def get_node(self, node_id: int) -> StoredNode:
        row = self._db.execute(
            "SELECT Node.id, stamp, pose, odometry, weight, arrays FROM Node JOIN Data ON Node.id = Data.id "
            "WHERE Node.id=?",
            (int(node_id),),
        ).fetchone()
        if row is None:
            raise KeyError(node_id)
        with np.load(io.BytesIO(row[5])) as npz:
            arrays = {k: npz[k] for k in npz.files}
        return StoredNode(row[0], row[1], _matrix(row[2], (4, 4)), _matrix(row[3], (4, 4)), row[4], arrays)

    def node_ids(self) -> list[int]:
        return [r[0] for r in self._db.execute("SELECT id FROM Node ORDER BY id")]

    def poses(self) -> dict[int, np.ndarray]:
        return {r[0]: _matrix(r[1], (4, 4)) for r in self._db.execute("SELECT id, pose FROM Node ORDER BY id")}

    def put_link(self, from_id: int, to_id: int, kind: str, transform: np.ndarray, information: np.ndarray) -> None:
        info = np.asarray(information, dtype=np.float64)
        with self._writing():
            self._db.execute(
                "INSERT OR REPLACE INTO Link VALUES (?, ?, ?, ?, ?)",
                (int(from_id), int(to_id), kind, _blob(transform), _blob(info)),
            )

    def get_arrays(self, node_id: int, names: tuple[str, ...]) -> dict[str, np.ndarray]:
        """Some of a node's stored arrays, the others left undecoded."""
        row = self._db.execute("SELECT arrays FROM Data WHERE id=?", (int(node_id),)).fetchone()
        if row is None:
            raise KeyError(f"{self.path}: no node {node_id} in the long-term memory")
        with np.load(io.BytesIO(row[0])) as npz:
            return {name: npz[name] for name in names}

    def links(self, kind: str | None = None) -> list[tuple[int, int, str, np.ndarray]]:
        query = (
            "SELECT from_id, to_id, type, transform FROM Link"
            + (" WHERE type=?" if kind else "")
            + " ORDER BY from_id, to_id"
        )
        rows = self._db.execute(query, (kind,) if kind else ())
        return [(a, b, t, _matrix(m, (4, 4))) for a, b, t, m in rows]

    def set_statistics(self, stats: dict[str, Any]) -> None:
        with self._writing():
            self._db.executemany(
                "INSERT OR REPLACE INTO Statistics VALUES (?, ?)", [(k, json.dumps(v)) for k, v in stats.items()]
            )

    def statistics(self) -> dict[str, Any]:
        return {k: json.loads(v) for k, v in self._db.execute("SELECT key, value FROM Statistics")}

    def size_bytes(self) -> int:
        """Bytes on disk, the write-ahead log included."""
        wal = self.path.with_name(self.path.name + "-wal")
        return self.path.stat().st_size + (wal.stat().st_size if wal.exists() else 0)
