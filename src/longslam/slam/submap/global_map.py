"""The global map of the submap method: optimised submaps fused into one TSDF, a 2D grid sliced
from it, and a mesh."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np

from longslam.io.ply import vertex_rows, write_ply
from longslam.gridmap import FREE, OCCUPIED, UNKNOWN, GridMap
from longslam.slam.submap.tsdf import BLOCK, TSDF


def fuse_submaps(submaps: list[tuple[TSDF, np.ndarray]], voxel: float, truncation: float) -> TSDF:
    """One world-frame TSDF from (submap TSDF, submap origin pose 4x4) pairs: every observed voxel
    of every submap moved by its submap's pose into the voxel of the global grid containing it,
    where the submaps' distances are averaged by weight."""
    fused = TSDF(voxel, truncation)
    for tsdf, pose in submaps:
        # A few blocks at a time: a whole submap's voxels as float64 index, centre and moved-centre
        # arrays raised the 1 km run's peak by 40 MB.
        for ijk, sdf, weight in tsdf.observed_chunks():
            if not len(ijk):
                continue
            centres = (ijk + 0.5) * tsdf.voxel
            fused.merge(centres @ pose[:3, :3].T + pose[:3, 3], sdf, weight)
    return fused


def grid_from_tsdf(
    tsdf: TSDF, surface: np.ndarray, floor_z: float,
    min_height: float = 0.2, max_height: float = 1.5, resolution: float = 0.1,
) -> GridMap:
    """2D occupancy from a world-frame TSDF and its iso-surface points: surface points between
    `min_height` and `max_height` above the floor are obstacles; the observed floor surface and
    observed voxels of that height band in front of a surface (distance > one voxel) are free.
    An obstacle wins over free."""
    surface = np.asarray(surface, dtype=np.float64).reshape(-1, 3)
    height = surface[:, 2] - floor_z
    occupied_xy = surface[(height >= min_height) & (height <= max_height), :2]
    free_parts = [surface[height < min_height, :2]]
    for ijk, sdf, _ in tsdf.observed_chunks():
        centres = (ijk + 0.5) * tsdf.voxel
        band = (centres[:, 2] - floor_z >= min_height) & (centres[:, 2] - floor_z <= max_height) & (sdf > tsdf.voxel)
        free_parts.append(centres[band, :2])
    free_xy = np.vstack(free_parts)
    every = np.vstack([occupied_xy, free_xy])
    if not len(every):
        return GridMap(np.full((1, 1), UNKNOWN, np.int8), float(resolution), (0.0, 0.0))
    lo = np.floor(every.min(axis=0) / resolution) - 1
    hi = np.floor(every.max(axis=0) / resolution) + 1
    cols, rows = (hi - lo + 1).astype(np.int64)
    data = np.full((rows, cols), UNKNOWN, np.int8)

    def cells(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        idx = (np.floor(xy / resolution) - lo).astype(np.int64)
        return idx[:, 1], idx[:, 0]

    data[cells(free_xy)] = FREE
    data[cells(occupied_xy)] = OCCUPIED
    return GridMap(data, float(resolution), (float(lo[0] * resolution), float(lo[1] * resolution)))


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
        cube = observed[:-1, :-1, :-1] & observed[1:, :-1, :-1] & observed[:-1, 1:, :-1] & observed[:-1, :-1, 1:] \
            & observed[1:, 1:, :-1] & observed[1:, :-1, 1:] & observed[:-1, 1:, 1:] & observed[1:, 1:, 1:]
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
    first (and trimesh's vertex merging) raised the 1 km run's peak by 85 MB. A vertex on a
    block's face is written once per block that meshes it (viewers show no seam)."""
    _, n_faces = write_ply(path, ((vertex_rows(v, normals), f) for v, normals, f in block_meshes(tsdf)),
                           comment="made by longslam (submap method)")
    if not n_faces:
        Path(path).unlink()
        return None
    return Path(path)
