"""A sparse, block-hashed TSDF (Voxblox's layout), integrated with NumPy.

Voxels of `voxel` metres are grouped in blocks of 16^3; a block exists only once a depth ray's
truncation band has touched it. Blocks live in a dict keyed by their packed integer index, their
voxels in two (blocks, 4096) arrays (signed distance, weight), so integration and lookups are
array operations over all touched voxels at once.

Integration follows Voxblox's "merged" integrator: the points of a depth image that fall in the
same voxel are bundled into one ray (their mean, with their count as weight), and each ray
updates the voxels of its truncation band [-truncation, +truncation] around the surface. The
signed distance of a voxel is measured from its centre along the ray; behind the surface the
weight drops linearly to zero at -truncation (Voxblox's weight drop-off). Free space beyond the
band is not carved.

A finished submap is `compact()`ed: the distances quantised to int8 (truncation / 127, 6 mm at
the default 0.8 m), the weights to float16, and blocks nobody observed dropped.
"""

from __future__ import annotations

import numpy as np

from longslam.core.errors import InputError
from longslam.core.frame import Intrinsics
from longslam.core.geometry.cells import group_cells_3d, pack_3d, unpack_3d

BLOCK = 16  # voxels per block side
BLOCK_VOXELS = BLOCK**3
MAX_WEIGHT = 10000.0  # Voxblox's max_weight


def _local_index(i: np.ndarray, j: np.ndarray, k: np.ndarray) -> np.ndarray:
    """A voxel's index within its block (x fastest), from its global indices per axis."""
    return (i & (BLOCK - 1)) + BLOCK * ((j & (BLOCK - 1)) + BLOCK * (k & (BLOCK - 1)))


def _dot(ax, ay, az, bx, by, bz):
    # The order np.einsum("ij,ij->i") sums in, so the numbers stay the same as with it.
    return (ax * bx + az * bz) + ay * by


def _band_cells(start: np.ndarray, direction: np.ndarray, offsets: np.ndarray, voxel: float) -> np.ndarray:
    """floor((start + direction * offset) / voxel) along one axis for every (ray, offset), ray
    by ray: (R * len(offsets),) int64. Computed in one buffer: the temporaries of the plain
    expression cost as much as the arithmetic."""
    cells = np.multiply(direction[:, None], offsets[None, :])
    np.add(start[:, None], cells, out=cells)
    np.divide(cells, voxel, out=cells)
    np.floor(cells, out=cells)
    return cells.astype(np.int64).reshape(-1)


_LOCAL = np.stack(np.meshgrid(np.arange(BLOCK), np.arange(BLOCK), np.arange(BLOCK), indexing="ij"), axis=-1)
_LOCAL = _LOCAL.transpose(2, 1, 0, 3).reshape(-1, 3)  # row k = voxel with local index k (x fastest)


class TSDF:
    """Sparse TSDF in its own frame (the submap's)."""

    def __init__(self, voxel: float = 0.2, truncation: float = 0.8, max_weight: float = MAX_WEIGHT):
        if not voxel > 0 or not truncation > voxel:
            raise InputError(f"TSDF needs voxel > 0 and truncation > voxel; got voxel={voxel}, truncation={truncation}")
        self.voxel = float(voxel)
        self.truncation = float(truncation)
        self.max_weight = float(max_weight)
        self._slot: dict[int, int] = {}
        self._keys = np.zeros(0, np.int64)  # block key of each slot
        self._sdf = np.zeros((0, BLOCK_VOXELS), np.float32)
        self._weight = np.zeros((0, BLOCK_VOXELS), np.float32)
        self._sdf_scale = 1.0  # stored value * scale = metres (1 until compacted to int8)
        self._sorted: tuple[np.ndarray, np.ndarray] | None = None  # (sorted keys, their slots)
        self.compacted = False

    # --- storage ------------------------------------------------------------------------------
    @property
    def num_blocks(self) -> int:
        return len(self._slot)

    @property
    def block_indices(self) -> np.ndarray:
        """(B, 3) integer indices of the allocated blocks."""
        return unpack_3d(self._keys[: len(self._slot)])

    @property
    def nbytes(self) -> int:
        """Bytes of the voxel arrays and the block index (dict entries counted at ~100 bytes)."""
        return int(self._sdf.nbytes + self._weight.nbytes + self._keys.nbytes + 100 * len(self._slot))

    def _allocate(self, block_keys: np.ndarray) -> np.ndarray:
        """Slots of unique block keys, allocating missing blocks."""
        if self.compacted:
            raise InputError("a compacted TSDF is read-only")
        # Existing blocks by binary search over the sorted keys (a dict lookup per block in
        # Python cost more); new ones take the next slots in the order they come.
        slots = self._find(block_keys)
        missing = np.flatnonzero(slots < 0)
        if len(missing):
            first = len(self._slot)
            need = first + len(missing)
            slots[missing] = np.arange(first, need)
            new = block_keys[missing]
            self._slot.update(zip(new.tolist(), range(first, need)))
            if need > len(self._sdf):
                self._grow(max(need, 2 * len(self._sdf), 16))
            self._keys[first:need] = new
            self._sorted = None
        return slots

    def _grow(self, capacity: int) -> None:
        for name in ("_sdf", "_weight"):
            old = getattr(self, name)
            grown = np.zeros((capacity, BLOCK_VOXELS), old.dtype)
            grown[: len(old)] = old
            setattr(self, name, grown)
        keys = np.zeros(capacity, np.int64)
        keys[: len(self._keys)] = self._keys
        self._keys = keys

    def reserve(self, blocks: int) -> None:
        """Room for `blocks` blocks in all. Growing copies the voxel arrays, which holds twice
        their memory for a moment; a TSDF whose size is known ahead (a fusion) grows once."""
        if self.compacted:
            raise InputError("a compacted TSDF is read-only")
        if blocks > len(self._sdf):
            self._grow(int(blocks))

    def _find(self, block_keys: np.ndarray) -> np.ndarray:
        """Slot of each block key, -1 where the block does not exist."""
        if self._sorted is None:
            keys = self._keys[: len(self._slot)]
            order = np.argsort(keys)
            self._sorted = (keys[order], order)
        keys, slots = self._sorted
        if not len(keys):
            return np.full(len(block_keys), -1, np.int64)
        pos = np.clip(np.searchsorted(keys, block_keys), 0, len(keys) - 1)
        return np.where(keys[pos] == block_keys, slots[pos], -1)

    def voxels(self, ijk: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance and weight of voxels (N, 3) int; weight 0 where never observed."""
        ijk = np.asarray(ijk, dtype=np.int64).reshape(-1, 3)
        slots = self._find(pack_3d(ijk >> 4))
        ok = slots >= 0
        sdf = np.zeros(len(ijk), np.float32)
        weight = np.zeros(len(ijk), np.float32)
        if ok.any():
            local = _local_index(*ijk[ok].T)
            sdf[ok] = self._sdf[slots[ok], local].astype(np.float32) * np.float32(self._sdf_scale)
            weight[ok] = self._weight[slots[ok], local]
        return sdf, weight

    def observed(
        self, min_weight: float = 0.0, blocks: slice | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Voxels with weight > min_weight (of the block slots in `blocks`, default all):
        (N, 3) indices, (N,) distances, (N,) weights."""
        first, stop, _ = (blocks or slice(None)).indices(len(self._slot))
        slot, local = np.nonzero(self._weight[first:stop] > min_weight)
        slot += first
        ijk = unpack_3d(self._keys[slot]) * BLOCK + _LOCAL[local]
        sdf = self._sdf[slot, local].astype(np.float32) * np.float32(self._sdf_scale)
        return ijk, sdf, self._weight[slot, local].astype(np.float32)

    def observed_chunks(self, min_weight: float = 0.0, blocks_per_chunk: int = 64):
        """`observed` a few blocks at a time, so that a large map never needs all its voxels'
        index arrays at once."""
        for start in range(0, len(self._slot), blocks_per_chunk):
            yield self.observed(min_weight, slice(start, start + blocks_per_chunk))

    def compact(self) -> None:
        """Make read-only and small: int8 distances, float16 weights, unobserved blocks dropped."""
        if self.compacted:
            return
        n = len(self._slot)
        keep = np.flatnonzero((self._weight[:n] > 0).any(axis=1))
        scale = self.truncation / 127.0
        self._sdf = np.clip(np.rint(self._sdf[keep] / scale), -127, 127).astype(np.int8)
        self._weight = np.minimum(self._weight[keep], 65000.0).astype(np.float16)
        self._keys = self._keys[keep].copy()
        self._slot = {int(k): i for i, k in enumerate(self._keys.tolist())}
        self._sdf_scale = scale
        self._sorted = None
        self.compacted = True

    def compacted_arrays(self) -> dict[str, np.ndarray]:
        """A compacted TSDF's state as plain arrays (block keys, int8 distances, float16 weights),
        what `from_compacted_arrays` rebuilds it from: how a finished submap goes to disk."""
        if not self.compacted:
            raise InputError("only a compacted TSDF is stored as arrays")
        n = len(self._slot)
        return {"keys": self._keys[:n], "sdf": self._sdf[:n], "weight": self._weight[:n]}

    @classmethod
    def from_compacted_arrays(
        cls,
        voxel: float,
        truncation: float,
        keys: np.ndarray,
        sdf: np.ndarray,
        weight: np.ndarray,
        max_weight: float = MAX_WEIGHT,
    ) -> "TSDF":
        """The compacted, read-only TSDF whose `compacted_arrays` these are."""
        tsdf = cls(voxel, truncation, max_weight)
        tsdf._keys = np.asarray(keys, np.int64)
        tsdf._sdf = np.asarray(sdf, np.int8).reshape(-1, BLOCK_VOXELS)
        tsdf._weight = np.asarray(weight, np.float16).reshape(-1, BLOCK_VOXELS)
        if not len(tsdf._keys) == len(tsdf._sdf) == len(tsdf._weight):
            raise InputError(
                f"a stored TSDF needs one distance and one weight block per key; got {len(tsdf._keys)} keys, "
                f"{len(tsdf._sdf)} and {len(tsdf._weight)} blocks"
            )
        tsdf._slot = {int(k): i for i, k in enumerate(tsdf._keys.tolist())}
        tsdf._sdf_scale = truncation / 127.0
        tsdf.compacted = True
        return tsdf

    # --- integration ----------------------------------------------------------------------------
    def integrate_points(
        self,
        points: np.ndarray,
        origin: np.ndarray,
        normals: np.ndarray | None = None,
        weights: np.ndarray | None = None,
    ) -> int:
        """Integrate surface points (N, 3) seen from `origin` (3,), both in this TSDF's frame.

        Points are first bundled per voxel (Voxblox's merged integrator). With `normals` (N, 3;
        NaN where unknown) a voxel's distance is measured to the bundle's tangent plane instead
        of along the ray: along the ray, a wall seen at a grazing angle reads far too distant
        for the voxels beside it, which moves the zero crossing behind the true surface.
        Returns the number of voxel updates.
        """
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        origin = np.asarray(origin, dtype=np.float64).reshape(3)
        if weights is None:
            weights = np.ones(len(points))
        if not len(points):
            return 0
        v, tau = self.voxel, self.truncation
        # Per coordinate rather than (N, 3) arrays: the same numbers, a third less time.
        px, py, pz = points[:, 0], points[:, 1], points[:, 2]
        ox, oy, oz = (float(c) for c in origin)
        # Bundle the points per voxel: mean point, summed weight.
        uniq, inverse = group_cells_3d(*(np.floor(c / v).astype(np.int64) for c in (px, py, pz)))
        n = len(uniq[0])
        w_sum = np.bincount(inverse, weights=weights, minlength=n)
        mx, my, mz = (np.bincount(inverse, weights=weights * c, minlength=n) / w_sum for c in (px, py, pz))
        rx, ry, rz = mx - ox, my - oy, mz - oz
        dist = np.sqrt(rx * rx + ry * ry + rz * rz)
        scale = np.maximum(dist, 1e-12)
        dx, dy, dz = rx / scale, ry / scale, rz / scale
        if normals is not None:
            normals = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
            n0, n1, n2 = normals[:, 0], normals[:, 1], normals[:, 2]
            known = np.flatnonzero(np.isfinite(n0) & np.isfinite(n1) & np.isfinite(n2))
            inverse_known = inverse[known]
            nsx, nsy, nsz = (np.bincount(inverse_known, weights=c[known], minlength=n) for c in (n0, n1, n2))
            nlen = np.sqrt(nsx * nsx + nsy * nsy + nsz * nsz)
            plane = nlen > 1e-9
            nscale = np.maximum(nlen, 1e-12)
            nx, ny, nz = (np.where(plane, c / nscale, -d) for c, d in ((nsx, dx), (nsy, dy), (nsz, dz)))
            # Facing the camera; a tangent plane seen nearly edge-on is not trusted.
            facing = -_dot(nx, ny, nz, dx, dy, dz)
            flip = np.where(facing < 0, -1.0, 1.0)
            plane &= np.abs(facing) > 0.1
            nx, ny, nz = (np.where(plane, c * flip, -d) for c, d in ((nx, dx), (ny, dy), (nz, dz)))
        else:
            nx, ny, nz = -dx, -dy, -dz
        ok = dist > 1e-6
        if not ok.all():
            mx, my, mz, dx, dy, dz, w_sum, nx, ny, nz = (a[ok] for a in (mx, my, mz, dx, dy, dz, w_sum, nx, ny, nz))
        # Samples every half voxel through the band; each sample names the voxel it falls in.
        offsets = np.arange(-tau, tau + 1e-9, 0.5 * v)
        i, j, k = (_band_cells(m, d, offsets, v) for m, d in ((mx, dx), (my, dy), (mz, dz)))
        # One update per (ray, voxel): a ray's samples are in order along it, so the samples it
        # takes in one voxel are adjacent and a comparison with the previous sample finds them.
        first = np.ones(len(i), bool)
        first[1:] = (i[1:] != i[:-1]) | (j[1:] != j[:-1]) | (k[1:] != k[:-1])
        first[:: len(offsets)] = True  # a ray's first sample
        sample = np.flatnonzero(first)
        ray_id = sample // len(offsets)
        i, j, k = i[sample], j[sample], k[sample]
        cx, cy, cz = (i + 0.5) * v, (j + 0.5) * v, (k + 0.5) * v
        along = _dot(cx - ox, cy - oy, cz - oz, dx[ray_id], dy[ray_id], dz[ray_id])
        sdf = _dot(cx - mx[ray_id], cy - my[ray_id], cz - mz[ray_id], nx[ray_id], ny[ray_id], nz[ray_id])
        keep = np.flatnonzero((sdf > -tau) & (along > 0))
        sdf = np.minimum(sdf[keep], tau)
        ray_id, i, j, k = ray_id[keep], i[keep], j[keep], k[keep]
        w = w_sum[ray_id]
        behind = sdf < -v
        w = np.where(behind, w * (tau + sdf) / (tau - v), w)
        # Merge updates of the same voxel from different rays.
        uv, inv = group_cells_3d(i, j, k)
        w_new = np.bincount(inv, weights=w, minlength=len(uv[0]))
        d_new = np.bincount(inv, weights=w * sdf, minlength=len(uv[0]))
        return self._accumulate(uv, w_new, d_new)

    def merge(self, points: np.ndarray, sdf: np.ndarray, weight: np.ndarray) -> None:
        """Fuse voxels of another TSDF, given as their centres moved into this frame (N, 3) with
        their distances and weights: each lands in the voxel containing it (weighted average)."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if not len(points):
            return
        uv, inv = group_cells_3d(*(np.floor(points[:, a] / self.voxel).astype(np.int64) for a in range(3)))
        w_new = np.bincount(inv, weights=weight, minlength=len(uv[0]))
        d_new = np.bincount(inv, weights=np.asarray(weight, np.float64) * sdf, minlength=len(uv[0]))
        self._accumulate(uv, w_new, d_new)

    def _accumulate(
        self, cells: tuple[np.ndarray, np.ndarray, np.ndarray], w_new: np.ndarray, wd_new: np.ndarray
    ) -> int:
        """Weighted running average: unique voxel indices (i, j, k arrays) in packed-key order,
        with their summed new weights and summed weight * distance. Allocates missing blocks;
        returns the number of voxels updated."""
        good = w_new > 0
        i, j, k = (c[good] for c in cells)
        w_new, wd_new = w_new[good], wd_new[good]
        blocks, binv = group_cells_3d(i >> 4, j >> 4, k >> 4)
        slots = self._allocate(pack_3d(np.column_stack(blocks)))[binv]
        # One flat index per voxel: gathers and scatters on the flat arrays take a third of the
        # time of the same (slot, local) pairs on the 2D ones. The arrays are made C-contiguous
        # (`_grow`), so the flat views write through.
        flat = slots * BLOCK_VOXELS + _local_index(i, j, k)
        weight, sdf = self._weight.reshape(-1), self._sdf.reshape(-1)
        assert self._weight.flags.c_contiguous and self._sdf.flags.c_contiguous
        w_old = weight[flat].astype(np.float64)
        d_old = sdf[flat].astype(np.float64)
        total = w_old + w_new
        sdf[flat] = ((w_old * d_old + wd_new) / total).astype(np.float32)
        weight[flat] = np.minimum(total, self.max_weight).astype(np.float32)
        return int(len(i))

    def integrate_depth(
        self,
        depth: np.ndarray,
        intrinsics: Intrinsics,
        camera_pose: np.ndarray,
        max_depth: float | None = None,
        stride: int = 1,
    ) -> int:
        """Integrate a depth image (metres, 0 = no return) taken at `camera_pose` (camera in this
        TSDF's frame, OpenCV axes). Returns the number of voxel updates (0 without valid depth)."""
        points, normals = depth_points(depth, intrinsics, stride, max_depth, with_normals=True)
        return self.integrate_camera_points(points, normals, camera_pose)

    def integrate_camera_points(self, points: np.ndarray, normals: np.ndarray, camera_pose: np.ndarray) -> int:
        """Integrate a depth image's `depth_points` (camera frame, with their normals) taken at
        `camera_pose` (camera in this TSDF's frame). Returns the number of voxel updates."""
        if not len(points):
            return 0
        pose = np.asarray(camera_pose, dtype=np.float64)
        rot = pose[:3, :3]
        return self.integrate_points(points @ rot.T + pose[:3, 3], pose[:3, 3], normals @ rot.T)

    # --- queries --------------------------------------------------------------------------------
    def interpolate(self, points: np.ndarray, min_weight: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Trilinear signed distance and its gradient at points (N, 3) in this TSDF's frame.

        Returns (distance (N,), gradient (N, 3), valid (N,) bool); valid where all eight
        surrounding voxel centres are observed (weight > min_weight).
        """
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3) / self.voxel - 0.5
        base = np.floor(p).astype(np.int64)
        f = p - base
        corners = np.array([[i, j, k] for k in (0, 1) for j in (0, 1) for i in (0, 1)], np.int64)
        ijk = (base[:, None, :] + corners[None, :, :]).reshape(-1, 3)
        sdf, weight = self.voxels(ijk)
        sdf = sdf.reshape(-1, 8).astype(np.float64)
        valid = (weight.reshape(-1, 8) > min_weight).all(axis=1)
        fx, fy, fz = f[:, 0:1], f[:, 1:2], f[:, 2:3]
        c = corners[None, :, :]
        wx = np.where(c[..., 0] == 1, fx, 1 - fx)
        wy = np.where(c[..., 1] == 1, fy, 1 - fy)
        wz = np.where(c[..., 2] == 1, fz, 1 - fz)
        value = (sdf * wx * wy * wz).sum(axis=1)
        sx = np.where(c[..., 0] == 1, 1.0, -1.0)
        sy = np.where(c[..., 1] == 1, 1.0, -1.0)
        sz = np.where(c[..., 2] == 1, 1.0, -1.0)
        grad = (
            np.column_stack(
                [
                    (sdf * sx * wy * wz).sum(axis=1),
                    (sdf * wx * sy * wz).sum(axis=1),
                    (sdf * wx * wy * sz).sum(axis=1),
                ]
            )
            / self.voxel
        )
        return value, grad, valid

    def surface_points(
        self,
        min_weight: float = 0.0,
        max_jump: float | None = None,
        with_normals: bool = True,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Iso-surface points: zero crossings between observed neighbouring voxels along x, y, z.

        Returns (points (N, 3) float32, unit normals (N, 3) float32 from the interpolated
        gradient, zero where it is undefined; None without `with_normals`). Crossings whose
        distances jump by more than `max_jump` (default: the truncation) are skipped: they join
        two unrelated surfaces seen from opposite sides, not one surface. Works a few blocks at a
        time to bound the temporary arrays.
        """
        max_jump = self.truncation if max_jump is None else max_jump
        all_points, all_normals = [], []
        for ijk, sdf, _ in self.observed_chunks(min_weight):
            pts = []
            for axis in range(3):
                step = np.zeros(3, np.int64)
                step[axis] = 1
                s1, w1 = self.voxels(ijk + step)
                cross = (w1 > min_weight) & (np.sign(sdf) != np.sign(s1)) & (np.abs(sdf - s1) <= max_jump) & (sdf != s1)
                s0 = sdf[cross].astype(np.float64)
                t = s0 / (s0 - s1[cross])
                p = (ijk[cross] + 0.5).astype(np.float64)
                p[:, axis] += t
                pts.append(p * self.voxel)
            points = np.vstack(pts)
            all_points.append(points.astype(np.float32))
            if with_normals and len(points):
                _, grad, _ = self.interpolate(points, min_weight)
                norm = np.linalg.norm(grad, axis=1)
                normals = np.where((norm > 1e-9)[:, None], grad / np.maximum(norm, 1e-9)[:, None], 0.0)
                all_normals.append(normals.astype(np.float32))
        points = np.vstack(all_points) if all_points else np.zeros((0, 3), np.float32)
        if not with_normals:
            return points, None
        return points, np.vstack(all_normals) if all_normals else np.zeros((0, 3), np.float32)

    def bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(min, max) corners of the observed voxels, metres; None when nothing is observed."""
        ijk, _, _ = self.observed()
        if not len(ijk):
            return None
        return ijk.min(axis=0) * self.voxel, (ijk.max(axis=0) + 1) * self.voxel


def depth_points(
    depth: np.ndarray,
    intrinsics: Intrinsics,
    stride: int = 1,
    max_depth: float | None = None,
    with_normals: bool = False,
):
    """Camera-frame points (N, 3) of the pixels with a return (every `stride`-th pixel); with
    `with_normals` also their normals (N, 3) from the neighbouring pixels' points (NaN where a
    neighbour has no return or lies across a depth edge)."""
    depth = np.asarray(depth)
    if depth.shape != (intrinsics.height, intrinsics.width):
        raise InputError(f"depth shape {depth.shape} does not match intrinsics {intrinsics.height}x{intrinsics.width}")
    stride = max(int(stride), 1)
    sub = depth[::stride, ::stride].astype(np.float64)
    ok = np.isfinite(sub) & (sub > 0)
    if max_depth is not None:
        ok &= sub <= max_depth
    if not ok.any():
        empty = np.zeros((0, 3))
        return (empty, empty) if with_normals else empty
    # Per coordinate rather than as (H, W, 3) stacks and np.cross: faster, the same numbers.
    ray_u = (np.arange(0, depth.shape[1], stride) - intrinsics.cx) / intrinsics.fx
    ray_v = (np.arange(0, depth.shape[0], stride) - intrinsics.cy) / intrinsics.fy
    z = np.where(ok, sub, np.nan)
    x = ray_u[None, :] * z
    y = ray_v[:, None] * z
    points = np.column_stack([x[ok], y[ok], z[ok]])
    if not with_normals:
        return points
    # Central differences along u and along v; the normal is their cross product.
    dux, duy, duz = (c[1:-1, 2:] - c[1:-1, :-2] for c in (x, y, z))
    dvx, dvy, dvz = (c[2:, 1:-1] - c[:-2, 1:-1] for c in (x, y, z))
    nx = duy * dvz - duz * dvy
    ny = duz * dvx - dux * dvz
    nz = dux * dvy - duy * dvx
    # Across a depth edge the neighbours belong to different surfaces: no normal there.
    span2 = np.maximum(dux * dux + duy * duy + duz * duz, dvx * dvx + dvy * dvy + dvz * dvz)
    limit = 8.0 * stride * z[1:-1, 1:-1] / intrinsics.fx
    with np.errstate(invalid="ignore", divide="ignore"):
        inverse_length = 1.0 / np.sqrt(nx * nx + ny * ny + nz * nz)
        inverse_length[span2 > limit * limit] = np.nan
    # Each component as an image (NaN on the border, where a pixel has no normal), read at the
    # points' pixels: filling the rows of an (N, 3) array through a mask took three times as long.
    normals = np.empty((len(points), 3))
    component = np.full(ok.shape, np.nan)
    for axis, c in enumerate((nx, ny, nz)):
        np.multiply(c, inverse_length, out=component[1:-1, 1:-1])
        normals[:, axis] = component[ok]
    return points, normals
