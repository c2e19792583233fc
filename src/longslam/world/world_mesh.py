"""A triangle mesh of a building with one texture atlas (or vertex colours), as plain numpy arrays."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class WorldMesh:
    """Triangles in world coordinates (z up, metres).

    `triangle_uvs[t, k]` is the texture position of corner k of triangle t in continuous pixel
    coordinates of `texture`: u = column, v = row, texel (r, c) covering [c, c+1) x [r, r+1), so
    the centre of texel (r, c) is (c + 0.5, r + 0.5). Either the texture (with uvs) or
    `vertex_colors` gives the colour; if both are present the renderer uses the texture.
    """

    vertices: np.ndarray  # (V, 3) float64
    triangles: np.ndarray  # (T, 3) int32
    triangle_uvs: np.ndarray | None = None  # (T, 3, 2) float32 texture pixel coordinates
    texture: np.ndarray | None = None  # (H, W, 3) uint8 RGB atlas
    vertex_colors: np.ndarray | None = None  # (V, 3) uint8 RGB

    def __post_init__(self) -> None:
        self.vertices = np.ascontiguousarray(self.vertices, dtype=np.float64).reshape(-1, 3)
        self.triangles = np.ascontiguousarray(self.triangles, dtype=np.int32).reshape(-1, 3)
        if self.triangle_uvs is not None:
            self.triangle_uvs = np.ascontiguousarray(self.triangle_uvs, dtype=np.float32).reshape(-1, 3, 2)
            if len(self.triangle_uvs) != len(self.triangles):
                raise ValueError(f"{len(self.triangle_uvs)} triangle uvs for {len(self.triangles)} triangles")
            if self.texture is None:
                raise ValueError("triangle_uvs given without a texture")
        if self.texture is not None:
            self.texture = np.ascontiguousarray(self.texture, dtype=np.uint8)
            if self.texture.ndim != 3 or self.texture.shape[2] != 3:
                raise ValueError(f"texture must be (H, W, 3), got {self.texture.shape}")
        if self.vertex_colors is not None:
            self.vertex_colors = np.ascontiguousarray(self.vertex_colors, dtype=np.uint8).reshape(-1, 3)
            if len(self.vertex_colors) != len(self.vertices):
                raise ValueError(f"{len(self.vertex_colors)} vertex colours for {len(self.vertices)} vertices")

    @property
    def is_textured(self) -> bool:
        return self.texture is not None and self.triangle_uvs is not None

    @property
    def nbytes(self) -> int:
        parts = (self.vertices, self.triangles, self.triangle_uvs, self.texture, self.vertex_colors)
        return int(sum(p.nbytes for p in parts if p is not None))

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(min xyz, max xyz) of the vertices."""
        return self.vertices.min(axis=0), self.vertices.max(axis=0)

    def to_open3d(self):
        """An Open3D legacy `TriangleMesh` (for viewing or writing with `open3d.io`).

        Open3D keeps uvs normalised to [0, 1] with v measured from the top row of the image,
        which is our pixel convention divided by the texture size.
        """
        import open3d as o3d

        mesh = o3d.geometry.TriangleMesh(
            o3d.utility.Vector3dVector(self.vertices), o3d.utility.Vector3iVector(self.triangles)
        )
        if self.is_textured:
            h, w = self.texture.shape[:2]
            uvs = self.triangle_uvs.reshape(-1, 2).astype(np.float64) / np.array([w, h], dtype=np.float64)
            mesh.triangle_uvs = o3d.utility.Vector2dVector(uvs)
            mesh.triangle_material_ids = o3d.utility.IntVector(np.zeros(len(self.triangles), dtype=np.int32))
            mesh.textures = [o3d.geometry.Image(self.texture)]
        if self.vertex_colors is not None:
            mesh.vertex_colors = o3d.utility.Vector3dVector(self.vertex_colors.astype(np.float64) / 255.0)
        return mesh
