"""Where a building mesh's floor is, and whether the mesh is in metres at all.

The floor is the largest horizontal surface near the lowest level that has room above it for the
robot: a surface whose upward ray travels at least the obstacle band's height before it hits
anything. That excludes the underside of a floor slab (the slab's own top is a few centimetres
above it), table tops (small) and ceilings (a roof's top may qualify, but it is higher than the
floor and the lowest qualifying level wins).
"""

from __future__ import annotations

import math

import numpy as np

from longslam.core.errors import InputError
from longslam.world.world_mesh import WorldMesh

HEADROOM = 1.5  # metres of free space a floor needs above it: the top of the obstacle band
LEVEL_BIN = 0.05  # metres: horizontal surfaces this close in height are one level
MAX_SAMPLES = 200_000
# A building in metres is at most this tall and this wide: anything bigger is in other units.
MAX_HEIGHT_M, MAX_WIDTH_M = 100.0, 3000.0


MIN_WIDTH_M = 1.0  # a building the robot can drive in is wider than this


def check_metres(mesh: WorldMesh, source: str, units: str = "m") -> None:
    """Refuse a mesh whose size (after `units`) says it is not in metres, naming the units it
    probably is in."""
    lo, hi = mesh.bounds
    size = hi - lo
    if max(size[0], size[1]) < MIN_WIDTH_M or size[2] < HEADROOM:
        factor = {"mm": 1e-3, "cm": 1e-2}.get(units)
        hint = (
            f"; it was read in {units} (--units {units}): if the file is in metres, leave out --units"
            if factor is not None and max(size[:2]) / factor >= MIN_WIDTH_M
            else ""
        )
        raise InputError(
            f"{source} is {size[0]:.3g} x {size[1]:.3g} x {size[2]:.3g} m (x, y, z): too small to be a building "
            f"(at least {MIN_WIDTH_M:g} m wide and {HEADROOM:g} m tall for the robot's headroom){hint}"
        )
    if size[2] <= MAX_HEIGHT_M and max(size[0], size[1]) <= MAX_WIDTH_M:
        return
    guess = next(
        (
            u
            for u, f in (("mm", 1e-3), ("cm", 1e-2))
            if size[2] * f <= MAX_HEIGHT_M and max(size[:2]) * f <= MAX_WIDTH_M
        ),
        None,
    )
    hint = f'; if it is in {guess}, give its units (--units {guess}, or units = "{guess}")' if guess else ""
    raise InputError(
        f"{source} is {size[0]:.0f} x {size[1]:.0f} x {size[2]:.0f} units (x, y, z): too big to be a building "
        f"in metres (at most {MAX_WIDTH_M:.0f} m wide and {MAX_HEIGHT_M:.0f} m tall){hint}"
    )


def find_floor(mesh: WorldMesh, source: str) -> float:
    """Height of the floor (metres, z up): see the module's description. Deterministic.

    Raises `InputError` naming `source` if no horizontal surface has `HEADROOM` above it.
    """
    import open3d as o3d

    tri = mesh.vertices[mesh.triangles]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    double_area = np.linalg.norm(cross, axis=1)
    flat = (double_area > 1e-9) & (np.abs(cross[:, 2]) > 0.98 * np.maximum(double_area, 1e-12))
    if not flat.any():
        raise InputError(f"{source} has no horizontal surface to be its floor; give the floor height (--floor Z)")
    tri, area = tri[flat], 0.5 * double_area[flat]
    spacing = max(0.1, math.sqrt(area.sum() / MAX_SAMPLES))
    counts = np.maximum(1, np.ceil(area / spacing**2)).astype(np.int64)
    which = np.repeat(np.arange(len(tri)), counts)
    rng = np.random.default_rng(0)
    r1, r2 = np.sqrt(rng.random(len(which)))[:, None], rng.random(len(which))[:, None]
    t = tri[which]
    points = (1 - r1) * t[:, 0] + r1 * (1 - r2) * t[:, 1] + r1 * r2 * t[:, 2]
    weights = (area / counts)[which]

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(mesh.vertices.astype(np.float32)), o3d.core.Tensor(mesh.triangles.astype(np.uint32))
    )
    rays = np.zeros((len(points), 6), dtype=np.float32)
    rays[:, :3] = points + [0.0, 0.0, 0.01]
    rays[:, 5] = 1.0
    headroom = scene.cast_rays(o3d.core.Tensor.from_numpy(rays))["t_hit"].numpy()  # inf: open above
    room = headroom >= HEADROOM
    if not room.any():
        raise InputError(
            f"{source}: no horizontal surface has {HEADROOM} m of free space above it, so no floor was found; "
            "give the floor height (--floor Z)"
        )
    z, w = points[room, 2], weights[room]
    zmin = float(z.min())
    bins = np.floor((z - zmin) / LEVEL_BIN).astype(np.int64)
    per_bin = np.bincount(bins, weights=w)
    # A level that straddles a bin edge counts in both neighbours.
    level = np.convolve(per_bin, np.ones(3), mode="same")
    lowest = int(np.flatnonzero(level >= 0.5 * level.max())[0])
    peak = lowest + int(np.argmax(level[lowest : lowest + 3])) if lowest + 1 < len(level) else lowest
    near = np.abs(bins - peak) <= 1
    return float(_weighted_median(z[near], w[near]))


def _weighted_median(values: np.ndarray, weights: np.ndarray) -> float:
    order = np.argsort(values)
    cum = np.cumsum(weights[order])
    return float(values[order][np.searchsorted(cum, 0.5 * cum[-1])])
