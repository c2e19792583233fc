"""A user's own building: a mesh file (PLY, OBJ, GLB/glTF, ...) turned into a `World`.

The mesh is turned z-up (glTF files are y-up), scaled to metres, and moved so that its floor
(found automatically, or given) is at z = 0, the plane the robot drives on. The ground-truth
occupancy grid is derived from the mesh the way a robot would see the building: surfaces between
0.2 m and 1.5 m above the floor are obstacles (the band the SLAM methods map), and floor visible
from above with nothing in that band is free.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from longslam.core.errors import InputError
from longslam.core.gridmap import FREE, OCCUPIED, UNKNOWN, GridMap
from longslam.world.floor import check_metres, find_floor
from longslam.world.mesh_reader import read_mesh_file
from longslam.world.model import World
from longslam.world.world_mesh import WorldMesh

OBSTACLE_BAND = (0.2, 1.5)  # metres above the floor
FLOOR_TOLERANCE = 0.1  # metres: how far a downward ray's hit may be from the floor and count as floor
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
UP_AXES = ("z", "y")
# glTF is y-up by its specification (so are Habitat's scene datasets); other formats are taken as z-up.
Y_UP_SUFFIXES = (".glb", ".gltf")
# y-up -> z-up: a quarter turn about x, (x, y, z) -> (x, -z, y), keeping the frame right-handed.
_Y_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def default_up(path: str | Path) -> str:
    return "y" if Path(path).suffix.lower() in Y_UP_SUFFIXES else "z"


def load_mesh_world(
    path: str | Path,
    floor_z: float | None = None,
    name: str | None = None,
    resolution: float = 0.05,
    units: str = "m",
    up: str | None = None,
    places: dict[str, tuple[float, float]] | None = None,
) -> World:
    """A `World` from a mesh file, its occupancy grid at `resolution` derived from the mesh.

    `up` is the file's up axis ("z", or "y" for glTF's convention; default by the file's suffix),
    `units` its length unit ("m", "cm", "mm"), `floor_z` the floor's height in metres after the
    mesh is turned z-up (found automatically if None). The world's mesh is moved so that the
    floor is at z = 0; x and y are kept, so waypoints and `places` are in the file's x, y (in
    metres). Raises `InputError` naming the file if it is missing, unreadable, has no triangles,
    is not in the units given, has no floor, or if `floor_z` is outside the mesh's height range.
    """
    path = Path(path)
    source = f"mesh file {path}"
    if units not in UNITS:
        raise InputError(f"{source}: unknown units {units!r}; valid values: {', '.join(UNITS)}")
    up = default_up(path) if up is None else up
    if up not in UP_AXES:
        raise InputError(f"{source}: unknown up axis {up!r}; valid values: {', '.join(UP_AXES)}")
    mesh = read_mesh_file(path)
    vertices = mesh.vertices @ _Y_TO_Z_UP.T if up == "y" else mesh.vertices
    mesh.vertices = np.ascontiguousarray(vertices * UNITS[units])
    check_metres(mesh, source, units)
    zmin, zmax = float(mesh.vertices[:, 2].min()), float(mesh.vertices[:, 2].max())
    if floor_z is None:
        floor_z = find_floor(mesh, source)
    elif not math.isfinite(floor_z) or not zmin - 0.01 <= floor_z <= zmax + 0.01:
        raise InputError(f"{source}: floor height {floor_z} m is outside the mesh's z range [{zmin:.3f}, {zmax:.3f}] m")
    mesh.vertices[:, 2] -= floor_z
    occupancy = occupancy_from_mesh(mesh, 0.0, resolution)
    if not np.any(occupancy.data == FREE):
        if not _has_horizontal_surface(mesh):
            raise InputError(
                f"{source}: the mesh has no floor surface at height {floor_z:.3f} m, nor any horizontal surface (walls "
                "only?); free space is where the floor is seen from above, so the mesh needs its floor"
            )
        raise InputError(
            f"{source}: no free floor at height {floor_z:.3f} m (nothing seen from above lies on it "
            "with the obstacle band clear); give the right floor height (--floor Z)"
        )
    return World(name or path.stem, mesh, occupancy, 0.0, dict(places or {}), None, source_floor_z=float(floor_z))


def _has_horizontal_surface(mesh: WorldMesh) -> bool:
    """Whether any triangle of the mesh faces up or down."""
    tri = mesh.vertices[mesh.triangles]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    norm = np.linalg.norm(cross, axis=1)
    flat = (norm > 1e-12) & (np.abs(cross[:, 2]) > 0.98 * np.maximum(norm, 1e-12))
    return bool(np.any(flat))


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
    scene.add_triangles(
        o3d.core.Tensor(mesh.vertices.astype(np.float32)), o3d.core.Tensor(mesh.triangles.astype(np.uint32))
    )
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
