"""A small building of a shape the university does not have, made with trimesh: a 10 x 4 m hall
with a crate in it, and a 2.4 m wide, 8 m long wing leaving its east side at 30 degrees, so no wall
of the wing is axis-aligned. Every surface is a mosaic of 0.25 m tiles of random colours (vertex
colours in the PLY, a texture in the GLB), so the SLAM methods find visual features in it.

The GLB is written y-up, as glTF wants it (and as Habitat's scenes are); the PLY z-up.

It lives in the package, not with the tests, because the tests, `benchmarks/own_building.py` and
`benchmarks/held_out.py` all drive it: `write_building` writes the meshes, `write_loop_route` them
and a route file through the hall and the wing.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

HEIGHT = 2.6  # metres, floor to ceiling
TILE = 0.25  # metres
WING_ANGLE = math.radians(30.0)
_D = np.array([math.cos(WING_ANGLE), math.sin(WING_ANGLE)])  # along the wing
_N = np.array([-_D[1], _D[0]])  # across it
_START = np.array([10.0, 2.0])  # the wing's centreline leaves the hall here
_W, _L = 2.4, 8.0  # width and length of the wing


def _x_crossing(point: np.ndarray) -> np.ndarray:
    """Where the line through `point` along the wing crosses the hall's east wall x = 10."""
    t = (10.0 - point[0]) / _D[0]
    return point + t * _D


_LOW, _HIGH = _START - _N * _W / 2, _START + _N * _W / 2  # corners of the wing's base
# The outline of the free floor, counter-clockwise.
OUTLINE = np.array(
    [
        (0.0, 0.0),
        (10.0, 0.0),
        _x_crossing(_LOW),
        _LOW + _L * _D,
        _HIGH + _L * _D,
        _x_crossing(_HIGH),
        (10.0, 4.0),
        (0.0, 4.0),
    ]
)
FLOOR_PIECES = [OUTLINE[[0, 1, 6, 7]], OUTLINE[[2, 3, 4, 5]]]  # the hall and the wing, both convex
CRATE = ((3.0, 1.7), (3.5, 2.3), 1.0)  # x0, y0 / x1, y1 / height
WING_END = tuple(_START + (_L - 1.2) * _D)  # a point on the floor near the end of the wing
WING_MID = tuple(_START + 4.0 * _D)


def _subdivide(p0: np.ndarray, u: np.ndarray, v: np.ndarray) -> list[np.ndarray]:
    """The parallelogram p0 + s u + t v (s, t in [0, 1]) cut into tiles of about TILE: (4, 3) corners each."""
    nu = max(1, int(round(np.linalg.norm(u) / TILE)))
    nv = max(1, int(round(np.linalg.norm(v) / TILE)))
    quads = []
    for i in range(nu):
        for j in range(nv):
            a = p0 + (i / nu) * u + (j / nv) * v
            quads.append(np.array([a, a + u / nu, a + u / nu + v / nv, a + v / nv]))
    return quads


def _convex_floor_tiles(polygon: np.ndarray, z: float) -> list[np.ndarray]:
    """Tiles of a convex quadrilateral (as 3D quads at height z), by bilinear subdivision."""
    a, b, c, d = (np.append(p, z) for p in polygon)
    nu = max(1, int(round(max(np.linalg.norm(b - a), np.linalg.norm(c - d)) / TILE)))
    nv = max(1, int(round(max(np.linalg.norm(d - a), np.linalg.norm(c - b)) / TILE)))

    def at(s, t):
        return (1 - s) * (1 - t) * a + s * (1 - t) * b + s * t * c + (1 - s) * t * d

    return [
        np.array(
            [at(i / nu, j / nv), at((i + 1) / nu, j / nv), at((i + 1) / nu, (j + 1) / nv), at(i / nu, (j + 1) / nv)]
        )
        for i in range(nu)
        for j in range(nv)
    ]


def building_quads() -> list[np.ndarray]:
    quads: list[np.ndarray] = []
    up = np.array([0.0, 0.0, HEIGHT])
    for piece in FLOOR_PIECES:
        quads += _convex_floor_tiles(piece, 0.0) + _convex_floor_tiles(piece, HEIGHT)
    ring = np.vstack([OUTLINE, OUTLINE[:1]])
    for p, q in zip(ring[:-1], ring[1:]):
        quads += _subdivide(np.append(p, 0.0), np.append(q - p, 0.0), up)
    (x0, y0), (x1, y1), top = CRATE
    corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)]
    for p, q in zip(corners[:-1], corners[1:]):
        quads += _subdivide(np.array([*p, 0.0]), np.array([q[0] - p[0], q[1] - p[1], 0.0]), np.array([0.0, 0.0, top]))
    quads += _subdivide(np.array([x0, y0, top]), np.array([x1 - x0, 0.0, 0.0]), np.array([0.0, y1 - y0, 0.0]))
    return quads


def write_building(folder: Path, seed: int = 0) -> tuple[Path, Path]:
    """Write building.ply (z-up, vertex colours) and building.glb (y-up, textured) into `folder`."""
    import trimesh
    from PIL import Image

    rng = np.random.default_rng(seed)
    quads = building_quads()
    vertices = np.concatenate(quads)
    k = 4 * np.arange(len(quads))[:, None]
    faces = np.concatenate([k + [0, 1, 2], k + [0, 2, 3]])
    colours = rng.integers(40, 250, (len(quads), 3)).astype(np.uint8)
    vertex_colours = np.repeat(colours, 4, axis=0)
    folder.mkdir(parents=True, exist_ok=True)
    ply = folder / "building.ply"
    trimesh.Trimesh(vertices, faces, vertex_colors=vertex_colours, process=False).export(ply)

    # The texture: 64 x 64 cells of 8 x 8 texels, each tile of the mesh mapped onto a random cell.
    cells = 64
    palette = rng.integers(40, 250, (cells * cells, 3)).astype(np.uint8)
    image = np.repeat(np.repeat(palette.reshape(cells, cells, 3), 8, axis=0), 8, axis=1)
    pick = rng.integers(0, cells * cells, len(quads))
    row, col = pick // cells, pick % cells
    corner = np.array([[0.2, 0.2], [0.8, 0.2], [0.8, 0.8], [0.2, 0.8]])
    uv = (np.stack([col, row], axis=1)[:, None, :] + corner[None]) / cells
    uv = uv.reshape(-1, 2)
    uv[:, 1] = 1.0 - uv[:, 1]  # trimesh's uvs have v up
    y_up = np.column_stack([vertices[:, 0], vertices[:, 2], -vertices[:, 1]])
    # A colour factor of 1: trimesh would otherwise write its default diffuse, 0.4, which glTF multiplies in.
    material = trimesh.visual.material.PBRMaterial(
        baseColorTexture=Image.fromarray(image), baseColorFactor=[255, 255, 255, 255]
    )
    visual = trimesh.visual.TextureVisuals(uv=uv, material=material)
    glb = folder / "building.glb"
    trimesh.Trimesh(y_up, faces, visual=visual, process=False).export(glb)
    return ply, glb


# A 49 m loop that drives the hall and the wing twice, so a method can close a loop across the
# angled wing's walls.
LOOP_WAYPOINTS = ((1.0, 1.0), (8.5, 2.6), WING_END, (8.5, 2.6), (1.5, 3.2), (1.0, 1.0), (8.5, 2.6), WING_END)


def write_loop_route(folder: Path, seed: int = 0) -> Path:
    """Write the building (`write_building`) and loop.json, a route file of LOOP_WAYPOINTS whose
    world is building.glb, into `folder`; returns the route file's path."""
    write_building(folder, seed)
    route = folder / "loop.json"
    route.write_text(json.dumps({"world": "building.glb", "waypoints": [list(map(float, w)) for w in LOOP_WAYPOINTS]}))
    return route
