"""A voxel filter fed a batch of points at a time, that never holds every point at once.

`average_3d` over a whole route's points needs them concatenated, in float64, with their voxel
indices, which on a long route is the run's peak, far above what mapping holds. Here each batch
is cut into slabs of `slab_voxels` voxels along x, and each slab's points go to a scratch file of
its own (buffered in RAM up to `buffer_points` points). At the end the slabs are filtered one at
a time, in ascending x, with `average_3d` itself.

The result is `average_3d(concatenated points).astype(float32)` to the bit: a voxel lies in one
slab; each slab's file keeps its points in the order they came, so each voxel's sum adds the
same numbers in the same order; and `average_3d` orders voxels by (i, j, k), so slabs taken in
ascending i come out in the batch filter's order.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import numpy as np

from longslam.core.geometry.cells import average_3d

# 0.8 m at keyframe's 5 cm voxels: a building is some hundred slabs. The largest slab's filter is
# the stream's peak, and its points grow with the laps: narrow slabs keep it small.
SLAB_VOXELS = 16
BUFFER_POINTS = 1 << 18  # points held in RAM (3 MB as float32) before they go to the slab files


class VoxelStream:
    """Voxel centroids of every point added, as `average_3d` gives them for their concatenation
    (float32). Points are stored as float32, as the keyframe method's cloud is made.

    Use as a context manager, or call `close`: the scratch files live in a temporary folder under
    `scratch_dir` (the system's temporary folder by default)."""

    def __init__(
        self,
        voxel: float,
        scratch_dir: str | Path | None = None,
        slab_voxels: int = SLAB_VOXELS,
        buffer_points: int = BUFFER_POINTS,
    ):
        if not voxel > 0:
            raise ValueError(f"voxel must be > 0 m, got {voxel}")
        if slab_voxels < 1 or buffer_points < 1:
            raise ValueError(f"slab_voxels and buffer_points must be >= 1, got {slab_voxels} and {buffer_points}")
        self.voxel = float(voxel)
        self.slab_voxels = int(slab_voxels)
        self.buffer_points = int(buffer_points)
        self._dir = Path(tempfile.mkdtemp(prefix=".voxels-", dir=scratch_dir))
        self._buffers: dict[int, list[np.ndarray]] = {}
        self._buffered = 0
        self._on_disk: set[int] = set()
        self._spent = False
        self.points_added = 0

    def __enter__(self) -> "VoxelStream":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Remove the scratch files (the result, if taken, is unaffected)."""
        self._buffers.clear()
        shutil.rmtree(self._dir, ignore_errors=True)

    def add(self, points: np.ndarray) -> None:
        """(N, 3) points, kept as float32."""
        if self._spent:
            raise RuntimeError("VoxelStream.add after result(): the stream has been filtered")
        points = np.ascontiguousarray(points, dtype=np.float32).reshape(-1, 3)
        if not len(points):
            return
        # The slab of each point's voxel, from the same float64 division `average_3d` makes.
        slab = np.floor(points[:, 0].astype(np.float64) / self.voxel).astype(np.int64) // self.slab_voxels
        order = np.argsort(slab, kind="stable")  # stable: each slab keeps the points' order
        slabs, starts = np.unique(slab[order], return_index=True)
        for s, part in zip(slabs.tolist(), np.split(points[order], starts[1:])):
            self._buffers.setdefault(s, []).append(part)
        self._buffered += len(points)
        self.points_added += len(points)
        if self._buffered > self.buffer_points:
            self._flush()

    def _path(self, slab: int) -> Path:
        return self._dir / f"slab{slab}.f32"

    def _flush(self) -> None:
        for s, parts in self._buffers.items():
            with open(self._path(s), "ab") as f:
                for part in parts:
                    part.tofile(f)
            self._on_disk.add(s)
        self._buffers.clear()
        self._buffered = 0

    def _slab_points(self, slab: int) -> np.ndarray:
        parts = [np.fromfile(self._path(slab), dtype=np.float32).reshape(-1, 3)] if slab in self._on_disk else []
        return np.concatenate(parts + self._buffers.get(slab, []))

    def result(self) -> np.ndarray:
        """(M, 3) float32 voxel centroids, in (i, j, k) order of their voxels. Once: the slab
        files are removed as they are read."""
        if self._spent:
            raise RuntimeError("VoxelStream.result called twice: the slab files are gone")
        self._spent = True
        # Each slab's centroids go to one more scratch file, read back whole at the end: a list
        # of them and its concatenation would hold the cloud twice.
        out, count = self._dir / "centroids.f32", 0
        with open(out, "wb") as f:
            for s in sorted(self._on_disk | set(self._buffers)):
                centroids = average_3d(self._slab_points(s), self.voxel).astype(np.float32)
                centroids.tofile(f)
                count += len(centroids)
                self._buffers.pop(s, None)
                self._path(s).unlink(missing_ok=True)  # frees the disk as the result fills
        cloud = np.fromfile(out, dtype=np.float32, count=3 * count).reshape(-1, 3)
        out.unlink()
        return cloud
