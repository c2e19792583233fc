"""A user's own building: a mesh file (PLY, OBJ, GLB, ...) plus the height of its floor.

The ground-truth occupancy grid is derived from the mesh the way a robot would see the building:
surfaces between 0.2 m and 1.5 m above the floor are obstacles (the band the SLAM methods map),
and floor visible from above with nothing in that band is free.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from longslam.errors import InputError
from longslam.gridmap import FREE, OCCUPIED, UNKNOWN, GridMap
from longslam.world.mesh import WorldMesh
from longslam.world.textures import pack_atlas
from longslam.world.world import World

OBSTACLE_BAND = (0.2, 1.5)  # metres above the floor
FLOOR_TOLERANCE = 0.1  # metres: how far a downward ray's hit may be from the floor and count as floor
GREY = (160, 160, 160)


def load_mesh_world(path: str | Path, floor_z: float = 0.0, name: str | None = None, resolution: float = 0.05) -> World:
    """A `World` from a mesh file, its occupancy grid at `resolution` derived from the mesh.

    Raises `InputError` naming the file if it is missing, unreadable or has no triangles, or if
    `floor_z` is outside the mesh's height range.
    """
    path = Path(path)
    mesh = load_mesh(path)
    zmin, zmax = float(mesh.vertices[:, 2].min()), float(mesh.vertices[:, 2].max())
    if not math.isfinite(floor_z) or not zmin - 0.01 <= floor_z <= zmax + 0.01:
        raise InputError(
            f"mesh file {path}: floor height {floor_z} m is outside the mesh's z range [{zmin:.3f}, {zmax:.3f}] m"
        )
    occupancy = occupancy_from_mesh(mesh, floor_z, resolution)
    return World(name or path.stem, mesh, occupancy, float(floor_z), {}, None)


def load_mesh(path: str | Path) -> WorldMesh:
    """Read a triangle mesh with its texture (several textures are packed into one atlas) or its
    vertex colours; a mesh with neither is flat grey."""
    import open3d as o3d  # here, not at the top: importing longslam.world should not cost a second

    path = Path(path)
    if path.is_dir():
        raise InputError(f"mesh file {path} is a folder; expected a mesh file (PLY, OBJ or GLB)")
    if not path.is_file():
        raise InputError(f"mesh file {path} does not exist")
    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        try:
            legacy = o3d.io.read_triangle_mesh(str(path), enable_post_processing=False)
        except Exception as err:  # Open3D raises RuntimeError for some malformed files
            raise InputError(f"mesh file {path} could not be read: {err}") from None
    vertices = np.asarray(legacy.vertices, dtype=np.float64)
    triangles = np.asarray(legacy.triangles, dtype=np.int64)
    if len(triangles) == 0 or len(vertices) == 0:
        raise InputError(
            f"mesh file {path} could not be read as a triangle mesh or has no triangles "
            "(expected a PLY, OBJ, GLB/glTF, OFF or STL file with faces)"
        )
    if not np.all(np.isfinite(vertices)):
        raise InputError(f"mesh file {path} has vertices that are not finite numbers")
    if triangles.min() < 0 or triangles.max() >= len(vertices):
        raise InputError(f"mesh file {path} has triangles that index missing vertices")

    # Materials without an image come through as empty images: they get a flat grey texel.
    textures = [_rgb_image(np.asarray(t)) if not t.is_empty() else np.full((1, 1, 3), GREY, np.uint8)
                for t in legacy.textures]
    uvs = np.asarray(legacy.triangle_uvs, dtype=np.float64)
    if any(t.size > 3 for t in textures) and len(uvs) == 3 * len(triangles):
        material = np.asarray(legacy.triangle_material_ids, dtype=np.int64)
        if len(material) != len(triangles):
            material = np.zeros(len(triangles), dtype=np.int64)
        material = np.where((material >= 0) & (material < len(textures)), material, 0)
        atlas = pack_atlas(textures)
        sizes = np.array([[t.shape[1], t.shape[0]] for t in textures], dtype=np.float64)
        # Open3D's uvs are in [0, 1] with v from the top row; ours are pixels in the atlas.
        pix = uvs.reshape(-1, 3, 2) * sizes[material][:, None, :] + atlas.offsets[material][:, None, :]
        return WorldMesh(vertices, triangles, pix.astype(np.float32), atlas.image)
    if legacy.has_vertex_colors():
        colors = np.clip(np.asarray(legacy.vertex_colors) * 255.0 + 0.5, 0, 255).astype(np.uint8)
        return WorldMesh(vertices, triangles, vertex_colors=colors)
    return WorldMesh(vertices, triangles, vertex_colors=np.tile(np.array(GREY, dtype=np.uint8), (len(vertices), 1)))


def _rgb_image(img: np.ndarray) -> np.ndarray:
    """Any Open3D texture (grey, RGBA, 16-bit, float) as (H, W, 3) uint8."""
    if img.ndim == 2:
        img = img[:, :, None]
    if img.dtype == np.uint16:
        img = (img >> 8).astype(np.uint8)
    elif img.dtype.kind == "f":
        img = np.clip(img * 255.0 + 0.5, 0, 255).astype(np.uint8)
    img = img.astype(np.uint8)
    if img.shape[2] == 1:
        img = np.repeat(img, 3, axis=2)
    return np.ascontiguousarray(img[:, :, :3])


def _sample_band(mesh: WorldMesh, z0: float, z1: float, spacing: float, max_points: int = 2_000_000):
    """Yield (N, 3) batches of points on the surface with z in [z0, z1], about one per
    `spacing` x `spacing` of area (deterministic: fixed-seed generator)."""
    rng = np.random.default_rng(0)
    tri = mesh.vertices[mesh.triangles]  # (T, 3, 3)
    in_band = (tri[:, :, 2].max(axis=1) >= z0) & (tri[:, :, 2].min(axis=1) <= z1)
    tri = tri[in_band]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    counts = np.maximum(1, np.ceil(area / spacing**2)).astype(np.int64)
    cum = np.cumsum(counts)
    start = 0
    while start < len(tri):
        # A batch of whole triangles holding about max_points samples.
        before = int(cum[start - 1]) if start else 0
        end = max(start + 1, int(np.searchsorted(cum, before + max_points, side="right")))
        which = np.repeat(np.arange(start, end), counts[start:end])
        r1, r2 = np.sqrt(rng.random(len(which)))[:, None], rng.random(len(which))[:, None]
        t = tri[which]
        pts = (1 - r1) * t[:, 0] + r1 * (1 - r2) * t[:, 1] + r1 * r2 * t[:, 2]
        yield pts[(pts[:, 2] >= z0) & (pts[:, 2] <= z1)]
        start = end
    # Corners too, so triangles smaller than a sample spacing still mark their cells.
    corners = tri.reshape(-1, 3)
    yield corners[(corners[:, 2] >= z0) & (corners[:, 2] <= z1)]


def occupancy_from_mesh(mesh: WorldMesh, floor_z: float, resolution: float = 0.05) -> GridMap:
    """Occupied (100) where the surface passes through the obstacle band above the floor; free (0)
    where a ray cast down from the top of the band lands on the floor (within FLOOR_TOLERANCE,
    on its upper side); unknown (-1) elsewhere."""
    import open3d as o3d

    lo, hi = mesh.bounds
    origin = (math.floor(lo[0] / resolution) * resolution, math.floor(lo[1] / resolution) * resolution)
    cols = int(math.ceil((hi[0] - origin[0]) / resolution)) + 1
    rows = int(math.ceil((hi[1] - origin[1]) / resolution)) + 1
    occupied = np.zeros((rows, cols), dtype=bool)
    z0, z1 = floor_z + OBSTACLE_BAND[0], floor_z + OBSTACLE_BAND[1]
    for pts in _sample_band(mesh, z0, z1, spacing=resolution / 2):
        qx, qy = (pts[:, 0] - origin[0]) / resolution, (pts[:, 1] - origin[1]) / resolution
        # A surface lying exactly on a cell border (walls of modelled buildings usually do) marks
        # the cells on both sides, so walls come out the same whichever way they face.
        for dx in (-1e-6, 1e-6):
            for dy in (-1e-6, 1e-6):
                c, r = np.floor(qx + dx).astype(np.int64), np.floor(qy + dy).astype(np.int64)
                ok = (r >= 0) & (r < rows) & (c >= 0) & (c < cols)
                occupied[r[ok], c[ok]] = True

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(mesh.vertices.astype(np.float32)), o3d.core.Tensor(mesh.triangles.astype(np.uint32)))
    # A floor hit counts if the floor faces up, the side a robot stands on. A ray that starts
    # inside a closed solid (a wall modelled as a box) hits the solid's bottom from within,
    # facing down, and must not make the wall's inside free.
    floor_up = np.zeros(rows * cols, dtype=bool)
    floor_down = np.zeros(rows * cols, dtype=bool)
    xs = origin[0] + (np.arange(cols) + 0.5) * resolution
    chunk_rows = max(1, 1_000_000 // cols)
    for r0 in range(0, rows, chunk_rows):
        ys = origin[1] + (np.arange(r0, min(rows, r0 + chunk_rows)) + 0.5) * resolution
        gx, gy = np.meshgrid(xs, ys)
        rays = np.zeros((gx.size, 6), dtype=np.float32)
        rays[:, 0], rays[:, 1], rays[:, 2], rays[:, 5] = gx.ravel(), gy.ravel(), z1, -1.0
        hits = scene.cast_rays(o3d.core.Tensor.from_numpy(rays))
        on_floor = np.abs((z1 - hits["t_hit"].numpy()) - floor_z) <= FLOOR_TOLERANCE
        nz = hits["primitive_normals"].numpy()[:, 2]
        span = slice(r0 * cols, r0 * cols + gx.size)
        floor_up[span], floor_down[span] = on_floor & (nz > 0), on_floor & (nz < 0)
    if not floor_up.any():  # the mesh's winding is flipped throughout: its floor faces down
        floor_up = floor_down
    data = np.full((rows, cols), UNKNOWN, dtype=np.int8)
    data[floor_up.reshape(rows, cols) & ~occupied] = FREE
    data[occupied] = OCCUPIED
    return GridMap(data, resolution, origin)
