"""A user's own building, end to end: a generated mesh with a wing at 30 degrees goes through
simulate -> run (each method) -> evaluate -> a two-run study, and its rendered depth is checked
against ray distances computed here, independently of Open3D, on the mesh file itself."""

from __future__ import annotations

import json
import sqlite3

import numpy as np
import pytest
import trimesh

from longslam.world.wing_building import CRATE, WING_END, WING_MID, write_building
from longslam.cli.main import main
from longslam.core.gridmap import FREE, OCCUPIED
from longslam.io.sequence import SequenceReader
from longslam.study.config import load_study
from longslam.study.driver import run_study
from longslam.world import load_mesh_world

pytestmark = pytest.mark.slow  # renders a building of its own and runs a study in it

ROUTE = {"world": "building.glb", "waypoints": [[1.0, 1.0], [8.5, 2.6], list(WING_END)]}
CAMERA = ["--width", "64", "--height", "48"]


@pytest.fixture(scope="module")
def building(tmp_path_factory):
    folder = tmp_path_factory.mktemp("own")
    write_building(folder)
    (folder / "r.json").write_text(json.dumps(ROUTE))
    return folder


def _ray_depths(vertices: np.ndarray, faces: np.ndarray, origin: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Nearest hit along each direction (Moller-Trumbore), in units of the direction's length;
    inf where a ray hits nothing."""
    tri = vertices[faces]
    a, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    p = np.cross(dirs[:, None, :], e2[None])  # (R, T, 3)
    det = np.einsum("rtk,tk->rt", p, e1)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = origin - a  # (T, 3)
    u = np.einsum("rtk,tk->rt", p, s) * inv
    q = np.cross(s, e1)  # (T, 3)
    v = np.einsum("rk,tk->rt", dirs, q) * inv
    t = np.einsum("tk,tk->t", e2, q)[None, :] * inv
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 1e-6)
    return np.where(hit, t, np.inf).min(axis=1)


def test_simulate_run_evaluate_study_on_a_glb_building(building, monkeypatch, capsys, tmp_path):
    monkeypatch.setenv("LONGSLAM_CACHE", str(tmp_path / "cache"))
    monkeypatch.chdir(building)
    assert main(["world", "--route", "r.json", "--out", "plan.png"]) == 0
    assert (building / "plan.png").stat().st_size > 0
    assert main(["simulate", "--route", "r.json", "--noise", "large", "--seed", "0", "--out", "seq", *CAMERA]) == 0
    assert "floor at z = 0.000 m" in capsys.readouterr().out
    reader = SequenceReader(building / "seq")
    assert 100 < len(reader) < 250 and reader.meta["world"].startswith("mesh:")
    # The route ends in the wing: the robot went up it at 30 degrees.
    end = reader.ground_truth.poses[-1, :2, 3]
    assert np.allclose(end, WING_END, atol=0.1)

    # Rendered depth (as written, 16-bit PNG) against ray distances to the triangles of the GLB
    # file, read by trimesh and turned z-up here: x, y, z = x_gltf, -z_gltf, y_gltf.
    mesh = trimesh.load(building / "building.glb", force="mesh", process=False)
    gltf = np.asarray(mesh.vertices, dtype=np.float64)
    vertices = np.column_stack([gltf[:, 0], -gltf[:, 2], gltf[:, 1]])
    k = reader.intrinsics
    u, v = np.meshgrid(np.arange(0, k.width, 4), np.arange(0, k.height, 4))
    dirs_cam = np.stack([(u - k.cx) / k.fx, (v - k.cy) / k.fy, np.ones_like(u, dtype=float)], axis=-1).reshape(-1, 3)
    checked = 0
    for i in (0, len(reader) // 2, len(reader) - 1):
        pose = reader.ground_truth.poses[i]
        expected = _ray_depths(vertices, np.asarray(mesh.faces), pose[:3, 3], dirs_cam @ pose[:3, :3].T)
        depth = reader[i].depth[v.ravel(), u.ravel()]
        seen = expected <= 8.0
        assert np.all(depth[~seen] == 0)
        assert np.allclose(depth[seen], expected[seen], atol=1e-3)  # PNG depth steps are 0.2 mm
        checked += int(seen.sum())
    assert checked > 400

    scores = {}
    for method in ("odometry", "keyframe", "submap"):
        assert main(["run", "--method", method, "seq", "--out", f"run-{method}"]) == 0
        capsys.readouterr()
        assert main(["evaluate", f"run-{method}", "seq", "--json"]) == 0
        scores[method] = json.loads(capsys.readouterr().out)
    for method, s in scores.items():
        assert np.isfinite(s["ate"]) and s["ate"] < 1.0, (method, s)
    assert scores["odometry"]["ate"] > 0.0  # large noise: dead reckoning drifts

    # A study file in a folder of its own names the mesh and the route relative to itself.
    (building / "studies").mkdir()
    (building / "studies" / "mine.toml").write_text(
        'world = "../building.glb"\nroutes = ["../r.json"]\nnoise = ["large"]\nmethods = ["odometry", "keyframe"]\n'
        "seeds = 1\n[camera]\nwidth = 64\nheight = 48\n"
    )
    summary = run_study(load_study(building / "studies" / "mine.toml"), building / "study", jobs=2, progress=False)
    assert summary.ran == 2 and summary.failed == 0
    with sqlite3.connect(building / "study" / "results.sqlite") as db:
        rows = db.execute("select method, status, ate, map_precision from runs order by method").fetchall()
    assert [(m, s) for m, s, _, _ in rows] == [("keyframe", "ok"), ("odometry", "ok")]
    assert rows[1][2] == pytest.approx(scores["odometry"]["ate"], rel=1e-9)  # the same frames and noise as the CLI's
    assert rows[0][3] is not None and 0.0 < rows[0][3] <= 1.0  # the map scored against the mesh's grid
    assert "`building.glb` (mesh" in (building / "study" / "report.md").read_text()
    # The same rendering served the CLI and the study: one cache entry for this camera.
    assert len([p for p in (tmp_path / "cache").iterdir() if p.is_dir()]) == 1


def test_ply_and_glb_make_the_same_world(building):
    ply = load_mesh_world(building / "building.ply")
    glb = load_mesh_world(building / "building.glb")
    assert not ply.mesh.is_textured and glb.mesh.is_textured
    assert np.allclose(ply.mesh.bounds[0], glb.mesh.bounds[0], atol=1e-5)
    assert np.allclose(ply.mesh.bounds[1], glb.mesh.bounds[1], atol=1e-5)
    assert ply.source_floor_z == pytest.approx(0.0, abs=1e-6) and glb.source_floor_z == pytest.approx(0.0, abs=1e-6)
    assert np.array_equal(ply.occupancy.data, glb.occupancy.data)
    grid = glb.occupancy
    # The wing's walls, at 30 degrees, and the crate (1 m tall, inside the obstacle band).
    d, n = np.array([np.cos(np.pi / 6), np.sin(np.pi / 6)]), np.array([-np.sin(np.pi / 6), np.cos(np.pi / 6)])
    along = np.array(WING_MID)[None] + np.linspace(-2.0, 2.0, 9)[:, None] * d
    assert np.all(grid.values_at(along) == FREE)
    assert np.all(grid.values_at(along + 1.2 * n) == OCCUPIED)
    assert np.all(grid.values_at(along - 1.2 * n) == OCCUPIED)
    assert np.all(grid.values_at(along + 1.5 * n) != FREE)  # outside the building
    (x0, y0), (x1, y1), _ = CRATE
    assert grid.values_at(np.array([[(x0 + x1) / 2, (y0 + y1) / 2]]))[0] != FREE
