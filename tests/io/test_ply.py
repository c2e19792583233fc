"""Our chunked PLY writer, read back by trimesh and Open3D."""

import numpy as np
import open3d as o3d
import pytest
import trimesh

from longslam.io.ply import vertex_rows, write_ply


def test_a_point_cloud_reads_back_in_trimesh_and_open3d(tmp_path):
    points = np.random.default_rng(0).uniform(-50, 150, (1000, 3))
    path = tmp_path / "cloud.ply"
    assert write_ply(path, [(vertex_rows(points[:400]), None), (vertex_rows(points[400:]), None)]) == (1000, 0)
    assert np.allclose(trimesh.load(path).vertices, points, atol=1e-4)
    assert np.allclose(np.asarray(o3d.io.read_point_cloud(str(path)).points), points, atol=1e-4)


def test_mesh_chunks_index_their_own_vertices(tmp_path):
    square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    tris = np.array([[0, 1, 2], [0, 2, 3]])
    normals = np.tile([0.0, 0.0, 1.0], (4, 1))
    chunks = [(vertex_rows(square + [2.0 * k, 0, 0], normals), tris) for k in range(3)]
    path = tmp_path / "mesh.ply"
    assert write_ply(path, chunks) == (12, 6)
    mesh = o3d.io.read_triangle_mesh(str(path))
    assert len(mesh.triangles) == 6 and mesh.has_vertex_normals()
    assert np.isclose(mesh.get_surface_area(), 3.0)
    loaded = trimesh.load(path, process=False)
    assert np.array_equal(loaded.faces[2:4], tris + 4)
    assert np.allclose(loaded.face_normals, [0, 0, 1])  # winding kept


def test_a_failure_midway_leaves_no_file(tmp_path):
    def chunks():
        yield vertex_rows(np.zeros((3, 3))), None
        raise RuntimeError("disk gone")

    with pytest.raises(RuntimeError):
        write_ply(tmp_path / "cloud.ply", chunks())
    assert list(tmp_path.iterdir()) == []


def test_a_run_folders_cloud_is_written_a_chunk_at_a_time(tmp_path, monkeypatch):
    import tracemalloc

    from longslam.run import folder

    points = np.random.default_rng(1).uniform(-50, 150, (2_000_000, 3)).astype(np.float32)
    tracemalloc.start()
    try:
        folder.write_point_cloud(tmp_path / "map.ply", points)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    # Whole, it took a float64 copy, the rows and their bytes: 4x the cloud's 24 MB.
    assert peak < 0.5 * points.nbytes, f"peak {peak / 1e6:.1f} MB writing {points.nbytes / 1e6:.1f} MB of points"
    loaded = np.asarray(o3d.io.read_point_cloud(str(tmp_path / "map.ply")).points)
    assert np.array_equal(loaded.astype(np.float32), points)  # every chunk, in order, to the bit

    monkeypatch.setattr(folder, "CLOUD_CHUNK", 7)  # chunk boundaries do not show in the file
    folder.write_point_cloud(tmp_path / "small.ply", points[:100].astype(np.float64))
    whole = tmp_path / "whole.ply"
    write_ply(whole, [(vertex_rows(points[:100]), None)], comment="made by longslam")
    assert (tmp_path / "small.ply").read_bytes() == whole.read_bytes()
