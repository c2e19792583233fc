"""Reading a building mesh file (PLY, OBJ, GLB/glTF, ...) with trimesh into a `WorldMesh`.

Every part of the file's scene is placed by its node transform; textured parts keep their
textures (packed into one atlas), coloured parts their vertex or face colours. The result is in
the file's own axes and units: `longslam.world.own_building` turns it upright and into metres.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from longslam.core.errors import InputError
from longslam.world.textures import pack_atlas
from longslam.world.world_mesh import WorldMesh

GREY = (160, 160, 160)
MESH_SUFFIXES = (".ply", ".obj", ".glb", ".gltf", ".off", ".stl")


@dataclass
class _Part:
    vertices: np.ndarray  # (V, 3)
    faces: np.ndarray  # (F, 3)
    uv: np.ndarray | None = None  # (V, 2) in [0, 1], v up (trimesh's convention)
    image: np.ndarray | None = None  # (H, W, 3) uint8
    colors: np.ndarray | None = None  # (V, 3) uint8


def read_mesh_file(path: str | Path) -> WorldMesh:
    """The triangles of a mesh file with their texture or colours (grey if it has neither).

    Raises `InputError` naming the file if it is missing, unreadable or has no triangles.
    """
    import trimesh

    path = Path(path)
    if path.is_dir():
        raise InputError(f"mesh file {path} is a folder; expected a mesh file (PLY, OBJ or GLB)")
    if not path.is_file():
        raise InputError(f"mesh file {path} does not exist")
    try:
        scene = trimesh.load(str(path), force="scene", process=False)
    except Exception as err:  # trimesh raises many kinds for malformed files
        raise InputError(f"mesh file {path} could not be read as a mesh: {type(err).__name__}: {err}") from None
    parts = []
    for node in scene.graph.nodes_geometry:
        transform, name = scene.graph[node]
        geometry = scene.geometry.get(name)
        if isinstance(geometry, trimesh.Trimesh) and len(geometry.faces):
            parts.append(_part(geometry, np.asarray(transform, dtype=np.float64)))
    if not parts:
        raise InputError(
            f"mesh file {path} has no triangles (expected a PLY, OBJ, GLB/glTF, OFF or STL file with faces)"
        )
    mesh = _combine(parts, path)
    if not np.all(np.isfinite(mesh.vertices)):
        raise InputError(f"mesh file {path} has vertices that are not finite numbers")
    return mesh


def _part(geometry, transform: np.ndarray) -> _Part:
    vertices = np.asarray(geometry.vertices, dtype=np.float64) @ transform[:3, :3].T + transform[:3, 3]
    faces = np.asarray(geometry.faces, dtype=np.int64)
    visual = geometry.visual
    kind = getattr(visual, "kind", None)
    if kind == "texture":
        material = visual.material
        image = getattr(material, "baseColorTexture", None)
        if image is None:
            image = getattr(material, "image", None)
        uv = getattr(visual, "uv", None)
        if image is not None and uv is not None and len(uv) == len(vertices):
            rgb = np.asarray(image.convert("RGB"), dtype=np.uint8)
            factor = getattr(material, "baseColorFactor", None)
            if factor is not None:  # glTF multiplies the texture by this factor
                rgb = np.clip(rgb * (np.asarray(factor[:3], dtype=np.float64) / 255.0) + 0.5, 0, 255).astype(np.uint8)
            return _Part(vertices, faces, uv=np.asarray(uv, dtype=np.float64), image=rgb)
        colour = np.asarray(material.main_color, dtype=np.uint8)[:3]
        return _Part(vertices, faces, colors=np.tile(colour, (len(vertices), 1)))
    if kind == "vertex":
        return _Part(vertices, faces, colors=np.asarray(visual.vertex_colors, dtype=np.uint8)[:, :3])
    if kind == "face":
        # One colour per face: each face gets corners of its own.
        colours = np.asarray(visual.face_colors, dtype=np.uint8)[:, :3]
        return _Part(
            vertices[faces].reshape(-1, 3),
            np.arange(3 * len(faces)).reshape(-1, 3),
            colors=np.repeat(colours, 3, axis=0),
        )
    return _Part(vertices, faces, colors=np.tile(np.array(GREY, np.uint8), (len(vertices), 1)))


def _combine(parts: list[_Part], path: Path) -> WorldMesh:
    offsets = np.cumsum([0] + [len(p.vertices) for p in parts])
    vertices = np.concatenate([p.vertices for p in parts])
    triangles = np.concatenate([p.faces + o for p, o in zip(parts, offsets)])
    if triangles.min() < 0 or triangles.max() >= len(vertices):
        raise InputError(f"mesh file {path} has triangles that index missing vertices")
    if not any(p.image is not None for p in parts):
        return WorldMesh(vertices, triangles, vertex_colors=np.concatenate([p.colors for p in parts]))
    # Some parts are textured: the renderer takes one texture for all triangles, so a coloured
    # part becomes a strip of texels, one per face colour (its faces' mean corner colour).
    images, corner_uvs = [], []
    for p in parts:
        if p.image is not None:
            assert p.uv is not None  # `_part` gives an image only with its uvs
            h, w = p.image.shape[:2]
            uv = p.uv[p.faces]  # (F, 3, 2)
            # Tiled textures (glTF's default wrap): move each triangle into the first tile.
            uv = uv - np.floor(uv.min(axis=1, keepdims=True))
            corner_uvs.append(np.stack([uv[..., 0] * w, (1.0 - uv[..., 1]) * h], axis=-1))
            images.append(p.image)
        else:
            assert p.colors is not None  # `_part` gives colours to every part without an image
            face_colours = p.colors[p.faces].mean(axis=1).round().astype(np.uint8)
            palette, which = np.unique(face_colours, axis=0, return_inverse=True)
            images.append(palette[None, :, :])
            centre = np.stack([which.reshape(-1) + 0.5, np.full(len(which), 0.5)], axis=-1)
            corner_uvs.append(np.repeat(centre[:, None, :], 3, axis=1))
    atlas = pack_atlas(images)
    pix = np.concatenate([uv + atlas.offsets[i] for i, uv in enumerate(corner_uvs)])
    return WorldMesh(vertices, triangles, pix.astype(np.float32), atlas.image)
