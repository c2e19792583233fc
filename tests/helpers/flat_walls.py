"""Flat walls rendered by the paper's camera: what the sensor-model and depth-trust tests
measure each model's statistics on."""

from __future__ import annotations

import numpy as np

from longslam.sim.camera import CameraSettings, RGBDCamera
from longslam.world.world_mesh import WorldMesh

# Camera at the origin looking along world +x (OpenCV axes: x right = world -y, y down = world -z).
LOOK_ALONG_X = np.eye(4)
LOOK_ALONG_X[:3, :3] = [[0, 0, 1], [-1, 0, 0], [0, -1, 0]]
SETTINGS = CameraSettings()  # the paper's 320 x 240, 90 degrees, depth to 8 m
K = SETTINGS.intrinsics


def _quads_mesh(quads: list[np.ndarray], texture: np.ndarray | None = None) -> WorldMesh:
    vertices = np.vstack(quads).astype(np.float64)
    triangles = []
    for q in range(len(quads)):
        b = 4 * q
        triangles += [[b, b + 1, b + 2], [b, b + 2, b + 3]]
    triangles = np.array(triangles, np.int32)
    if texture is None:
        return WorldMesh(vertices, triangles, vertex_colors=np.full((len(vertices), 3), 150, np.uint8))
    h, w = texture.shape[:2]
    corner = np.array([[0, 0], [w, 0], [w, h], [0, h]], np.float32)
    uvs = np.concatenate([[corner[[0, 1, 2]], corner[[0, 2, 3]]] for _ in quads]).astype(np.float32)
    return WorldMesh(vertices, triangles, triangle_uvs=uvs, texture=texture)


def square_wall(x: float, half: float = 30.0) -> np.ndarray:
    """A square wall across the view at distance x, facing the camera."""
    return np.array([[x, -half, -half], [x, half, -half], [x, half, half], [x, -half, half]], float)


def render(quads: list[np.ndarray], texture: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    return RGBDCamera(_quads_mesh(quads, texture), SETTINGS, nthreads=1).render(LOOK_ALONG_X)


TEXTURED_HALF = 6.0  # m: a 12 m wall fills the 90 deg view to 6 m
