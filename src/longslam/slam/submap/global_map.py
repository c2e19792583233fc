"""The global map of the submap method: optimised submaps fused into one TSDF, a 2D grid sliced
from it, and a mesh."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import numpy as np

from longslam.core.geometry.cells import pack_3d
from longslam.core.gridmap import FREE, OCCUPIED, UNKNOWN, GridMap
from longslam.core.memory_release import release_free_memory
from longslam.io.ply import vertex_rows, write_ply
from longslam.slam.submap.tsdf import BLOCK, TSDF


def fuse_submaps(load: Callable[[int], TSDF], poses: Sequence[np.ndarray], voxel: float, truncation: float) -> TSDF:
    """One world-frame TSDF from submaps (`load(i)` gives submap i's TSDF, `poses[i]` its origin
    pose 4x4): every observed voxel of every submap moved by its submap's pose into the voxel of
    the global grid containing it, where the submaps' distances are averaged by weight.

    Each submap is loaded twice (its blocks counted, then merged) and held only while it is used,
    so `load` may read it from disk (SubmapStore): the submaps are never all held beside the
    fused map."""
    fused = TSDF(voxel, truncation)
    # The blocks the fused map will have, counted first, so that its arrays are allocated once:
    # growing them by doubling would copy the arrays, with the old copy still held.
    blocks = np.zeros(0, np.int64)
    for i, pose in enumerate(poses):
        blocks = np.unique(
            np.concatenate([blocks] + [_fused_blocks(moved, voxel) for moved, _, _ in _moved_voxels(load(i), pose)])
        )
    fused.reserve(len(blocks))
    del blocks
    for i, pose in enumerate(poses):
        tsdf = load(i)
        for moved, sdf, weight in _moved_voxels(tsdf, pose):
            fused.merge(moved, sdf, weight)
        del tsdf
        release_free_memory(collect=False)  # the submap's arrays lived on the heap
    return fused


def _moved_voxels(tsdf: TSDF, pose: np.ndarray) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(voxel centres moved by `pose`, distances, weights) of a submap, a few blocks at a time: a
    whole submap's voxels as float64 index, centre and moved-centre arrays at once would raise the
    run's peak."""
    for ijk, sdf, weight in tsdf.observed_chunks():
        if len(ijk):
            centres = (ijk + 0.5) * tsdf.voxel
            yield centres @ pose[:3, :3].T + pose[:3, 3], sdf, weight


def _fused_blocks(points: np.ndarray, voxel: float) -> np.ndarray:
    """Packed keys of the blocks `TSDF.merge` puts these points in."""
    return np.unique(pack_3d(np.column_stack([np.floor(points[:, a] / voxel).astype(np.int64) >> 4 for a in range(3)])))


COMPACT_ROWS = 250_000  # cell rows gathered before duplicates are merged (grid_from_tsdf)
SLICE_VOXELS = 4_096  # band voxels sampled at once: bounds the interpolation's temporaries (~15 MB)


def grid_from_tsdf(
    tsdf: TSDF,
    surface: np.ndarray,
    floor_z: float,
    min_height: float = 0.2,
    max_height: float = 1.5,
    resolution: float = 0.1,
) -> GridMap:
    """2D occupancy sliced from a world-frame TSDF between `min_height` and `max_height` above
    the floor, at the grid's own resolution.

    Each grid cell whose centre lies under an observed voxel of that height band is sampled at
    the voxel's height, the distance interpolated trilinearly from the eight voxels around (the
    voxel's own distance where a neighbour is unobserved): within half a cell diagonal of the
    surface the cell is occupied, farther in front of it free, behind it unknown. An obstacle at
    any height wins. Sampling every cell, rather than marking the cell of each voxel centre,
    leaves no rows of unknown cells between voxels coarser than the grid and draws walls as
    continuous lines; the iso-surface points between `min_height` and `max_height` (`surface`)
    are obstacles too, so that a wall thinner than a voxel, whose two faces' distances never
    change sign between voxel centres, still shows. Works a few blocks at a time."""
    surface = np.asarray(surface, dtype=np.float64).reshape(-1, 3)
    height = surface[:, 2] - floor_z
    occupied_xy = surface[(height >= min_height) & (height <= max_height), :2]
    res = float(resolution)
    per_side = int(np.ceil(tsdf.voxel / res)) + 1
    step = np.stack(np.meshgrid(np.arange(per_side), np.arange(per_side), indexing="ij"), axis=-1).reshape(-1, 2)
    occupied_keys, free_keys = [np.floor(occupied_xy / res).astype(np.int64)], []
    for ijk, sdf, _ in tsdf.observed_chunks():
        centres = (ijk + 0.5) * tsdf.voxel
        band = (centres[:, 2] - floor_z >= min_height) & (centres[:, 2] - floor_z <= max_height)
        if not band.any():
            continue
        in_band = np.flatnonzero(band)
        for part in range(0, len(in_band), SLICE_VOXELS):
            pick = in_band[part : part + SLICE_VOXELS]
            occupied_part, free_part = _slice_cells(tsdf, ijk[pick], sdf[pick], centres[pick, 2], res, step)
            occupied_keys.append(occupied_part)
            free_keys.append(free_part)
        # A cell is sampled once per voxel layer and chunk: merge as the lists grow, so that
        # only about one row per cell is held however long the route.
        for keys in (occupied_keys, free_keys):
            if len(keys) > 1 and sum(len(k) for k in keys) > COMPACT_ROWS:
                keys[:] = [_unique_rows(np.vstack(keys))]
    occupied = _unique_rows(np.vstack(occupied_keys))
    free = _unique_rows(np.vstack(free_keys)) if free_keys else np.zeros((0, 2), np.int64)
    every = np.vstack([occupied, free])
    if not len(every):
        return GridMap(np.full((1, 1), UNKNOWN, np.int8), res, (0.0, 0.0))
    lo = every.min(axis=0).astype(np.int64) - 1
    cols, rows = every.max(axis=0) - lo + 2
    data = np.full((rows, cols), UNKNOWN, np.int8)
    data[free[:, 1] - lo[1], free[:, 0] - lo[0]] = FREE
    data[occupied[:, 1] - lo[1], occupied[:, 0] - lo[0]] = OCCUPIED
    return GridMap(data, res, (float(lo[0] * res), float(lo[1] * res)))


def _slice_cells(
    tsdf: TSDF,
    ijk: np.ndarray,
    sdf: np.ndarray,
    z: np.ndarray,
    res: float,
    step: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """(occupied, free) grid cells under some band voxels (`grid_from_tsdf`): the cells whose
    centres lie in each voxel's footprint, sampled at the voxel's height."""
    near = res * np.sqrt(0.5)
    lo_xy = ijk[:, :2] * tsdf.voxel
    # The cells whose centres lie in each voxel's footprint [lo, lo + voxel).
    first = np.ceil(lo_xy / res - 0.5).astype(np.int64)
    cells = (first[:, None, :] + step[None, :, :]).reshape(-1, 2)
    xy = (cells + 0.5) * res
    owner = np.repeat(np.arange(len(lo_xy)), len(step))
    inside = np.all((xy >= lo_xy[owner] - 1e-9) & (xy < lo_xy[owner] + tsdf.voxel - 1e-9), axis=1)
    cells, xy, owner = cells[inside], xy[inside], owner[inside]
    distance, _, valid = tsdf.interpolate(np.column_stack([xy, z[owner]]))
    distance = np.where(valid, distance, sdf[owner])
    return _unique_rows(cells[np.abs(distance) <= near]), _unique_rows(cells[distance > near])


def _unique_rows(cells: np.ndarray) -> np.ndarray:
    """Unique (N, 2) int64 cell indices, through one packed key per row."""
    if not len(cells):
        return np.zeros((0, 2), np.int64)
    cells = cells.astype(np.int64)
    lo = cells.min(axis=0)
    span = cells[:, 1].max() - lo[1] + 1
    keys = np.unique((cells[:, 0] - lo[0]) * span + (cells[:, 1] - lo[1]))
    return np.column_stack([keys // span + lo[0], keys % span + lo[1]]).astype(np.int32)


def block_meshes(tsdf: TSDF) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Marching cubes block by block (each block padded by its neighbours' first voxel layer),
    only over cubes whose eight voxels are observed. Yields per block (vertices (V, 3) in metres,
    their normals (V, 3) towards free space, triangles (T, 3) indexing this block's vertices)."""
    from skimage.measure import marching_cubes

    blocks = tsdf.block_indices
    grid = np.stack(np.meshgrid(*(np.arange(BLOCK + 1),) * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    for block in blocks:
        ijk = block * BLOCK + grid
        sdf, weight = tsdf.voxels(ijk)
        observed = (weight > 0).reshape((BLOCK + 1,) * 3)
        if observed.sum() < 8:
            continue
        volume = sdf.reshape((BLOCK + 1,) * 3)
        if volume[observed].min() > 0 or volume[observed].max() < 0:
            continue
        # A cube counts only if all its corners are observed: erode the mask by one cube.
        cube = (
            observed[:-1, :-1, :-1]
            & observed[1:, :-1, :-1]
            & observed[:-1, 1:, :-1]
            & observed[:-1, :-1, 1:]
            & observed[1:, 1:, :-1]
            & observed[1:, :-1, 1:]
            & observed[:-1, 1:, 1:]
            & observed[1:, 1:, 1:]
        )
        # As in TSDF.surface_points: a cube whose distances span more than the truncation joins
        # two unrelated surfaces (the clamped far side of a wall and a ray that grazed past it),
        # and would draw a sheet of mesh in the wall's shadow.
        n = volume.shape[0] - 1
        corners = np.stack([volume[a : a + n, b : b + n, c : c + n] for a in (0, 1) for b in (0, 1) for c in (0, 1)])
        cube &= corners.max(axis=0) - corners.min(axis=0) <= tsdf.truncation
        if not cube.any():
            continue
        mask = np.zeros_like(observed)
        mask[:-1, :-1, :-1] = cube
        volume = np.where(observed, volume, tsdf.truncation)
        try:
            # "ascent": normals up the distance, out of the wall into free space.
            v, f, normals, _ = marching_cubes(volume, level=0.0, mask=mask, gradient_direction="ascent")
        except (ValueError, RuntimeError):
            continue
        yield (v + block * BLOCK + 0.5) * tsdf.voxel, normals, f


def mesh_arrays(tsdf: TSDF) -> tuple[np.ndarray, np.ndarray]:
    """The whole mesh at once: (vertices (V, 3), triangles (T, 3)); see `block_meshes`."""
    verts, tris, offset = [], [], 0
    for v, _, f in block_meshes(tsdf):
        verts.append(v)
        tris.append(f + offset)
        offset += len(v)
    if not verts:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    return np.vstack(verts), np.vstack(tris)


def write_mesh(tsdf: TSDF, path: Path) -> Path | None:
    """Write the TSDF's mesh as binary PLY (float32 vertices with their normals, triangles);
    None when there is no surface. Block by block (io/ply.py): building the whole mesh in memory
    first (and trimesh's vertex merging) would raise the run's peak. A vertex on a
    block's face is written once per block that meshes it (viewers show no seam)."""
    _, n_faces = write_ply(
        path,
        ((vertex_rows(v, normals), f) for v, normals, f in block_meshes(tsdf)),
        comment="made by longslam (submap method)",
    )
    if not n_faces:
        Path(path).unlink()
        return None
    return Path(path)
