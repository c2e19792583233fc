"""The simulated RGB-D camera: ray casting into a `WorldMesh` with Open3D's Embree scene.

Pixel convention (OpenCV's): integer pixel coordinates are pixel centres, so pixel (u, v) looks
along ((u - cx) / fx, (v - cy) / fy, 1) in the camera frame. With cx = width / 2 the optical axis
passes through the centre of pixel (width / 2, height / 2). This is the model that
`cv2.projectPoints`, `cv2.solvePnP` and Open3D's depth back-projection use with the same
intrinsics, so a method that back-projects the rendered depth recovers the mesh exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from longslam.core.errors import InputError
from longslam.core.frame import Intrinsics
from longslam.io.sequence.layout import DEPTH_SCALE
from longslam.world.world_mesh import WorldMesh

# A fixed sun-like light from above and to one side: walls of different orientations, the floor
# and the ceiling each get a different brightness, as under real lighting.
_LIGHT = np.array([0.45, 0.3, 0.84]) / np.linalg.norm([0.45, 0.3, 0.84])
_AMBIENT, _DIFFUSE, _HEADLIGHT = 0.4, 0.3, 0.3  # sum 1: the brightest surface shows its texture as is


# The user-facing names of the camera settings (CLI options --width ... --camera-height, a study
# file's [camera] keys) -> CameraSettings fields.
CAMERA_KEYS = {
    "width": "width",
    "height": "height",
    "fov": "hfov_deg",
    "max_depth": "max_depth",
    "camera_height": "camera_height",
}
# Errors name a setting as the user gives it (fov), not by its field (hfov_deg).
_KEY_OF_FIELD = {field: key if key == field else f"{key} ({field})" for key, field in CAMERA_KEYS.items()}
# A sequence stores depth as 16-bit PNGs scaled by DEPTH_SCALE: a camera that sees farther could
# render frames no sequence can hold, found only when the first frame is written.
MAX_STORABLE_DEPTH = 65535 / DEPTH_SCALE


# The renderer holds about 60 bytes a pixel (rays, directions, hits, images) and every frame is
# written as two PNGs: beyond 4K UHD a typo (100000 x 100000) would be a MemoryError, not a camera.
MAX_SIDE = 7680
MAX_PIXELS = 3840 * 2160


@dataclass(frozen=True)
class CameraSettings:
    width: int = 320  # pixels
    height: int = 240  # pixels
    hfov_deg: float = 90.0
    max_depth: float = 8.0  # metres; returns beyond it read 0, like a real depth sensor's range
    camera_height: float = 1.25  # metres above the floor

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value <= 0:
                raise InputError(f"camera setting {_KEY_OF_FIELD[name]} must be a positive integer, got {value!r}")
            if value > MAX_SIDE:
                raise InputError(f"camera setting {name} must be at most {MAX_SIDE} pixels, got {value!r}")
        if self.width * self.height > MAX_PIXELS:
            raise InputError(
                f"camera {self.width} x {self.height} = {self.width * self.height} pixels is more than "
                f"{MAX_PIXELS} (3840 x 2160) a frame; the renderer would need about "
                f"{self.width * self.height * 60 / 1e9:.1f} GB"
            )
        checks = {
            "hfov_deg": (lambda v: 0.0 < v < 180.0, "a number in (0, 180) degrees"),
            "max_depth": (
                lambda v: 0.0 < v <= MAX_STORABLE_DEPTH,
                f"a positive number of metres, at most {MAX_STORABLE_DEPTH:.3f} (the largest depth "
                f"16-bit depth images scaled by {DEPTH_SCALE:g} store)",
            ),
            "camera_height": (lambda v: v > 0.0, "a positive number of metres"),
        }
        for name, (ok, expected) in checks.items():
            value = getattr(self, name)
            if (
                isinstance(value, bool)
                or not isinstance(value, (int, float, np.floating, np.integer))
                or not math.isfinite(value)
                or not ok(value)
            ):
                raise InputError(f"camera setting {_KEY_OF_FIELD[name]} must be {expected}, got {value!r}")

    @property
    def intrinsics(self) -> Intrinsics:
        return Intrinsics.from_fov(self.width, self.height, self.hfov_deg)


class RGBDCamera:
    """Renders colour and depth images of a mesh from camera-in-world poses.

    The Embree scene is built once; each `render` casts one ray per pixel on `nthreads` threads
    (0 lets Open3D use every core; with several rendering processes, give each 1).
    A camera reuses its ray buffer between calls: use one camera per thread.
    """

    def __init__(self, mesh: WorldMesh, settings: CameraSettings = CameraSettings(), nthreads: int = 0):
        if len(mesh.triangles) == 0:
            raise InputError("cannot render a mesh with no triangles")
        self.mesh = mesh
        self.settings = settings
        self.intrinsics = settings.intrinsics
        self.nthreads = int(nthreads)
        # Imported here: Open3D costs hundreds of MB of resident memory, which a run that only reads
        # camera settings (every `longslam` command) should not pay.
        import open3d as o3d

        self._o3d = o3d
        self._scene = o3d.t.geometry.RaycastingScene()
        self._scene.add_triangles(
            o3d.core.Tensor(mesh.vertices.astype(np.float32)), o3d.core.Tensor(mesh.triangles.astype(np.uint32))
        )
        k = self.intrinsics
        u, v = np.meshgrid(np.arange(k.width, dtype=np.float64), np.arange(k.height, dtype=np.float64))
        # z = 1 in the camera frame, so the hit distance Open3D reports (in units of the ray
        # direction's length) is the depth itself.
        dirs = np.stack([(u - k.cx) / k.fx, (v - k.cy) / k.fy, np.ones_like(u)], axis=-1).reshape(-1, 3)
        self._dirs_cam = dirs.astype(np.float32).reshape(-1, 1, 3)  # the layout cv2.transform takes
        self._inv_len = (1.0 / np.linalg.norm(dirs, axis=1)).astype(np.float32)
        self._rays = np.empty((k.height * k.width, 6), dtype=np.float32)
        # Shading from the fixed light depends on the triangle only: one lookup per pixel.
        tri = mesh.vertices[mesh.triangles]
        normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
        # Two-sided: external meshes have arbitrary winding; only the angle to the light matters.
        # One extra entry, 0, for rays that hit nothing (they are sent to index T).
        self._light = np.append(_AMBIENT + _DIFFUSE * np.abs(normals @ _LIGHT), 0.0).astype(np.float32)
        n_tri = len(mesh.triangles)
        if mesh.is_textured:
            assert mesh.texture is not None and mesh.triangle_uvs is not None  # what is_textured means
            h, w = mesh.texture.shape[:2]
            # Clamped to the texture at the corners, so that every interpolated position is
            # inside it (uvs outside [0, 1] in an external mesh are clamped, not tiled).
            uvs = np.clip(mesh.triangle_uvs.astype(np.float32), 0.0, np.array([w, h], dtype=np.float32) - 1e-3)
            # Per triangle: uv of corner 0 and the two edge vectors, as one row of 6, one gather per pixel.
            affine = np.concatenate([uvs[:, 0], uvs[:, 1] - uvs[:, 0], uvs[:, 2] - uvs[:, 0]], axis=1)
            self._uv_affine = np.vstack([affine, np.zeros((1, 6))]).astype(np.float32)
            # RGBA as one uint32 per texel: gathering 4 bytes as a word is much faster than 3 bytes.
            rgba = np.zeros((h, w, 4), dtype=np.uint8)
            rgba[:, :, :3] = mesh.texture
            self._texels = rgba.reshape(-1).view(np.uint32)
            self._tex_w = w
            self._index_type = np.int32 if h * w < 2**31 else np.int64
            self._corner_colors = None
        else:
            colors = mesh.vertex_colors if mesh.vertex_colors is not None else np.full((len(mesh.vertices), 3), 160)
            self._corner_colors = np.vstack([colors[mesh.triangles].reshape(n_tri, 9), np.zeros((1, 9))]).astype(
                np.float32
            )

    def render(self, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """rgb (H, W, 3) uint8 and depth (H, W) float32 metres (camera-frame z, 0 for no return)
        seen from `pose`, the 4x4 camera-in-world transform.

        Colour is shown for every surface hit, also beyond `max_depth`: a colour camera sees
        further than a depth sensor measures.
        """
        pose = np.asarray(pose, dtype=np.float64)
        if pose.shape != (4, 4) or not np.all(np.isfinite(pose)):
            raise InputError(f"camera pose must be a finite 4x4 matrix, got shape {pose.shape}")
        k = self.intrinsics
        # (np.take and cv2 below are several times faster than fancy indexing and small matmuls,
        # which matters at 77k pixels and 50+ frames a second.)
        dirs_world = cv2.transform(self._dirs_cam, pose[:3, :3].astype(np.float32)).reshape(-1, 3)
        self._rays[:, :3] = pose[:3, 3]
        self._rays[:, 3:] = dirs_world
        hits = self._scene.cast_rays(self._o3d.core.Tensor.from_numpy(self._rays), nthreads=self.nthreads)
        t_hit = hits["t_hit"].numpy()
        depth = np.where(t_hit <= self.settings.max_depth, t_hit, np.float32(0.0))  # inf (no hit) fails the test

        # Every pixel goes through the same arithmetic (no gathers of the hit subset); pixels with
        # no hit look up the extra all-zero triangle and come out black.
        tri = np.minimum(hits["primitive_ids"].numpy(), len(self._light) - 1).view(np.int32)
        normals = hits["primitive_normals"].numpy()  # zero for no hit
        headlight = np.abs(np.einsum("ij,ij->i", normals, dirs_world)) * self._inv_len
        shade = np.take(self._light, tri) + np.float32(_HEADLIGHT) * headlight  # <= 1
        colour = self._surface_colour(tri, hits["primitive_uvs"].numpy())  # (H, W, 3) uint8
        shade3 = cv2.merge([shade.reshape(k.height, k.width)] * 3)
        rgb = cv2.multiply(colour, shade3, dtype=cv2.CV_8U)
        return rgb, depth.reshape(k.height, k.width)

    def _surface_colour(self, tri: np.ndarray, bary: np.ndarray) -> np.ndarray:
        """(H, W, 3) uint8 colour: nearest texel of the atlas, or interpolated vertex colours."""
        k = self.intrinsics
        b1, b2 = bary[:, 0], bary[:, 1]  # Embree: p = (1 - b1 - b2) p0 + b1 p1 + b2 p2
        if self._corner_colors is None:
            a = np.take(self._uv_affine, tri, axis=0)
            u = a[:, 0] + b1 * a[:, 2] + b2 * a[:, 4]
            v = a[:, 1] + b1 * a[:, 3] + b2 * a[:, 5]
            # Truncation is floor here (uvs are non-negative); a hair below 0 from rounding truncates to 0 too.
            it = self._index_type
            texel = np.take(self._texels, v.astype(it) * self._tex_w + u.astype(it))
            return cv2.cvtColor(texel.view(np.uint8).reshape(k.height, k.width, 4), cv2.COLOR_RGBA2RGB)
        c = np.take(self._corner_colors, tri, axis=0)
        b0 = 1.0 - b1 - b2
        out = c[:, 0:3] * b0[:, None] + c[:, 3:6] * b1[:, None] + c[:, 6:9] * b2[:, None]
        return (out + 0.5).astype(np.uint8).reshape(k.height, k.width, 3)
