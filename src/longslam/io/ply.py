"""Binary PLY files of points and triangle meshes, written in chunks.

Why not trimesh or Open3D here: importing either costs tens to hundreds of MB of resident
memory, and building a whole mesh in memory more: each would be the run's peak (issue 11 bounds
it). A PLY is a text header and packed little-endian rows, so the rows are
streamed to scratch files as they come and joined under the header once their counts are known.
The files open in MeshLab, Open3D, trimesh and CloudCompare (tests/test_ply.py reads them back
with trimesh and Open3D).
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from longslam.io.atomic import atomic_path, naming_the_file

POINT = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4")])
POINT_NORMAL = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("nx", "<f4"), ("ny", "<f4"), ("nz", "<f4")])
_FACE = np.dtype([("n", "u1"), ("v", "<i4", (3,))])
_PLY_TYPES = {"<f4": "float", "<f8": "double", "|u1": "uchar", "<i4": "int"}


def vertex_rows(points: np.ndarray, normals: np.ndarray | None = None) -> np.ndarray:
    """(N, 3) points (and their (N, 3) normals) as PLY vertex rows."""
    points = np.asarray(points).reshape(-1, 3)
    rows = np.empty(len(points), POINT if normals is None else POINT_NORMAL)
    for axis, name in enumerate("xyz"):
        rows[name] = points[:, axis]
        if normals is not None:
            rows["n" + name] = np.asarray(normals).reshape(-1, 3)[:, axis]
    return rows


def _header(vertex: np.dtype, n_vertices: int, n_faces: int | None, comment: str) -> bytes:
    lines = ["ply", "format binary_little_endian 1.0"]
    lines += [f"comment {comment}"] if comment else []
    lines.append(f"element vertex {n_vertices}")
    lines += [f"property {_PLY_TYPES[vertex.fields[name][0].str]} {name}" for name in vertex.names]
    if n_faces is not None:
        lines += [f"element face {n_faces}", "property list uchar int vertex_indices"]
    lines.append("end_header")
    return ("\n".join(lines) + "\n").encode("ascii")


def write_ply(
    path: str | Path, chunks: Iterable[tuple[np.ndarray, np.ndarray | None]], comment: str = ""
) -> tuple[int, int]:
    """Write chunks of (vertex rows, triangles (T, 3) indexing that chunk's rows, or None) as one
    PLY (a point cloud when no chunk has triangles). Atomic: a failure leaves no file.
    Returns (vertices, triangles) written."""
    path = Path(path)
    n_vertices = n_faces = 0
    vertex_dtype = None
    with naming_the_file(path), tempfile.TemporaryDirectory(dir=path.parent, prefix=f".{path.name}-") as scratch:
        vertex_file, face_file = Path(scratch) / "vertices", Path(scratch) / "faces"
        with open(vertex_file, "wb") as vf, open(face_file, "wb") as ff:
            for rows, triangles in chunks:
                if vertex_dtype is None:
                    vertex_dtype = rows.dtype
                elif rows.dtype != vertex_dtype:
                    raise ValueError(f"every chunk of {path} needs vertex rows {vertex_dtype}, got {rows.dtype}")
                if triangles is not None and len(triangles):
                    faces = np.empty(len(triangles), _FACE)
                    faces["n"] = 3
                    faces["v"] = np.asarray(triangles) + n_vertices
                    faces.tofile(ff)  # no bytes copy of the chunk
                    n_faces += len(faces)
                np.ascontiguousarray(rows).tofile(vf)
                n_vertices += len(rows)
        with atomic_path(path, overwrite=True) as tmp, open(tmp, "wb") as out:
            out.write(_header(vertex_dtype or POINT, n_vertices, n_faces if n_faces else None, comment))
            for part in (vertex_file, face_file):
                with open(part, "rb") as src:
                    shutil.copyfileobj(src, out, 1 << 20)
    return n_vertices, n_faces
