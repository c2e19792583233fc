"""A mesh file as a world: references pinned by content, floors, units, waypoint errors, and the
places a world is taken (CLI, route files, study files)."""

from __future__ import annotations

import json
import re
import shutil

import numpy as np
import pytest
import trimesh

from longslam.world.wing_building import WING_END, write_building
from longslam.cli.main import main
from longslam.core.errors import InputError
from longslam.sim.simulate import cache_key
from longslam.sim.camera import CameraSettings
from longslam.sim.drive import drive_route
from longslam.sim.follower import FollowerSettings
from longslam.sim.navigation import NavigationGrid
from longslam.sim.routes import Route, get_route, load_route_file
from longslam.study.config import StudyConfigError, load_study
from longslam.study.spec import plan_runs
from longslam.world import load_mesh_world, load_world, world_key, world_ref
from longslam.world.reference import MeshSpec


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    path = tmp_path_factory.mktemp("meshes")
    write_building(path)
    return path


def _transformed(folder, name: str, scale: float = 1.0, shift=(0.0, 0.0, 0.0)):
    mesh = trimesh.load(folder / "building.ply", process=False)
    mesh.vertices = (np.asarray(mesh.vertices) + shift) * scale
    out = folder / name
    mesh.export(out)
    return out


def _same_grid(a, b) -> bool:
    """The same cells but for a few on cell borders, where float32 coordinates in the file round
    the other way once moved or scaled."""
    return a.data.shape == b.data.shape and a.origin == b.origin and np.count_nonzero(a.data != b.data) <= 1e-3 * a.data.size


def test_floor_off_zero_is_found_and_moved_to_zero(folder):
    path = _transformed(folder, "storey3.ply", shift=(0.0, 0.0, 6.4))
    world = load_mesh_world(path)
    assert world.source_floor_z == pytest.approx(6.4, abs=1e-4) and world.floor_z == 0.0
    assert world.mesh.bounds[0][2] == pytest.approx(0.0, abs=1e-4)
    reference = load_mesh_world(folder / "building.ply")
    assert _same_grid(world.occupancy, reference.occupancy)
    # Given by hand: the same; a floor in mid-air leaves no free floor and says so.
    assert _same_grid(load_mesh_world(path, floor_z=6.4).occupancy, reference.occupancy)
    with pytest.raises(InputError, match=r"storey3.ply: no free floor at height 7.500"):
        load_mesh_world(path, floor_z=7.5)


def test_millimetres_are_refused_unless_declared(folder):
    path = _transformed(folder, "mm.ply", scale=1000.0)
    with pytest.raises(InputError, match=r"mm.ply is 17528 x 7039 x 2600 units.*--units mm"):
        load_mesh_world(path)
    world = load_mesh_world(path, units="mm")
    assert _same_grid(world.occupancy, load_mesh_world(folder / "building.ply").occupancy)
    with pytest.raises(InputError, match="unknown units 'inch'"):
        load_mesh_world(path, units="inch")


def test_world_reference_pins_the_content(folder, tmp_path):
    copy = tmp_path / "b.ply"
    shutil.copy(folder / "building.ply", copy)
    ref = world_ref("b.ply", base=tmp_path)
    spec = MeshSpec.from_ref(ref)
    assert spec.path == str(copy) and spec.up == "z" and spec.floor is None
    assert world_ref(ref) == ref and world_ref("university") == "university"
    route = Route("r", ref, ((1.0, 1.0), (8.5, 2.6)))
    key = cache_key(route, CameraSettings(), FollowerSettings())
    assert key.startswith(f"{world_key(ref)}-r-") and world_key(ref).startswith("b-")

    # Moved: the same world, the same cache entry.
    moved = tmp_path / "elsewhere" / "b.ply"
    moved.parent.mkdir()
    shutil.copy(copy, moved)
    ref_moved = world_ref(str(moved))
    assert cache_key(Route("r", ref_moved, route.waypoints), CameraSettings(), FollowerSettings()) == key

    # Edited: another world; the old reference is refused rather than loaded with new content.
    mesh = trimesh.load(copy, process=False)
    mesh.vertices = np.asarray(mesh.vertices) * [1.0, 1.0, 1.1]
    mesh.export(copy)
    edited = world_ref(str(copy))
    assert cache_key(Route("r", edited, route.waypoints), CameraSettings(), FollowerSettings()) != key
    with pytest.raises(InputError, match=r"b.ply has changed since this world was given"):
        load_world(ref)
    assert load_world(edited).mesh.bounds[1][2] == pytest.approx(2.86, abs=1e-4)

    # Options change the world too.
    assert world_key(world_ref({"mesh": str(moved), "floor": 0.0})) != world_key(ref_moved)


def test_world_reference_errors(folder, tmp_path):
    with pytest.raises(InputError, match=r"unknown world 'nowhere'; valid values: a world name \(university, annex\) or a mesh file"):
        world_ref("nowhere")
    with pytest.raises(InputError, match=r"mesh file .*missing.glb does not exist"):
        world_ref("missing.glb", base=tmp_path)
    with pytest.raises(InputError, match=r"unknown key 'flor'; valid keys: mesh, floor"):
        world_ref({"mesh": "building.ply", "flor": 0}, base=folder)
    with pytest.raises(InputError, match="floor must be a height in metres, got 'low'"):
        world_ref({"mesh": "building.ply", "floor": "low"}, base=folder)
    bad = tmp_path / "places.json"
    bad.write_text('{"door": [1, "x"]}')
    with pytest.raises(InputError, match=r"places file .*places.json: 'door' = \[1, 'x'\]; expected \[x, y\]"):
        world_ref({"mesh": "building.ply", "places": str(bad)}, base=folder)


def test_named_places_from_a_places_file(folder, tmp_path):
    places = tmp_path / "places.json"
    places.write_text(json.dumps({"hall": [1.0, 1.0], "wing_end": list(WING_END)}))
    ref = world_ref({"mesh": str(folder / "building.ply"), "places": str(places)})
    world = load_world(ref)
    assert world.places["wing_end"] == pytest.approx(WING_END)
    driven = drive_route(world, Route("p", ref, ("hall", "wing_end")))
    assert np.allclose(driven.xyyaw[-1, :2], WING_END, atol=0.1)
    with pytest.raises(InputError, match=r"waypoint 1 names place 'lobby', which world 'building.ply' does not have; places: hall, wing_end"):
        drive_route(world, Route("p", ref, ("hall", "lobby")))
    bare = world_ref(str(folder / "building.ply"))
    with pytest.raises(InputError, match=r"places: \(none\) \(give a places file: --places FILE\)"):
        drive_route(load_world(bare), Route("p", bare, ("hall", "lobby")))


def _nearest(message: str) -> tuple[float, float]:
    found = re.search(r"the nearest (?:free|reachable) point is \((-?[\d.]+), (-?[\d.]+)\)", message)
    assert found, message
    return float(found.group(1)), float(found.group(2))


def test_waypoint_off_the_floor_names_the_nearest_free_point(folder):
    ref = world_ref(str(folder / "building.ply"))
    world = load_world(ref)
    with pytest.raises(InputError, match=r"route 'r' waypoint 1 \(12.00, 0.30\) is not on free floor") as err:
        drive_route(world, Route("r", ref, ((1.0, 1.0), (12.0, 0.3))))
    nearest = _nearest(str(err.value))
    nav = NavigationGrid(world.occupancy)
    assert nav.is_traversable(nearest) and np.hypot(nearest[0] - 12.0, nearest[1] - 0.3) < 2.0


def test_unreachable_waypoint_names_the_nearest_reachable_point(folder):
    # Two copies of the building 30 m apart: the second cannot be reached from the first.
    one = trimesh.load(folder / "building.ply", process=False)
    two = one.copy()
    two.apply_translation((30.0, 0.0, 0.0))
    path = folder / "twins.ply"
    trimesh.util.concatenate([one, two]).export(path)
    ref = world_ref(str(path))
    world = load_world(ref)
    with pytest.raises(InputError, match=r"waypoint 2 \(31.00, 1.00\) cannot be reached from route 'r' waypoint 0 \(1.00, 1.00\)") as err:
        drive_route(world, Route("r", ref, ((1.0, 1.0), (8.0, 2.0), (31.0, 1.0))))
    nearest = _nearest(str(err.value))
    assert nearest[0] < 18.0 and NavigationGrid(world.occupancy).is_traversable(nearest)


def test_route_files_name_their_world_relative_to_themselves(folder, tmp_path):
    routes = tmp_path / "routes"
    routes.mkdir()
    route_file = routes / "r.json"
    route_file.write_text(json.dumps({"world": f"{folder}/building.glb", "waypoints": [[1, 1], [8.5, 2.6]]}))
    route = load_route_file(route_file)
    assert MeshSpec.from_ref(route.world).path == str(folder / "building.glb")
    shutil.copy(folder / "building.ply", routes / "b.ply")
    (routes / "rel.json").write_text(json.dumps({"world": {"mesh": "b.ply", "floor": 0.0}, "waypoints": [[1, 1], [8.5, 2.6]]}))
    rel = load_route_file(routes / "rel.json")
    assert MeshSpec.from_ref(rel.world).path == str(routes / "b.ply") and MeshSpec.from_ref(rel.world).floor == 0.0
    with pytest.raises(InputError, match=r"r.json: world 'building.glb' is not the world given \('university'\)"):
        load_route_file(route_file, "university")
    with pytest.raises(InputError, match=r"route 'demo' is a route of world 'university', not of 'building.ply'"):
        get_route("demo", world_ref(str(folder / "building.ply")))
    text = routes / "plain.txt"
    text.write_text("1 1\n8.5 2.6\n")
    assert get_route(str(text), route.world).world == route.world


def test_cli_takes_a_mesh_world_and_refuses_mistakes(folder, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("LONGSLAM_CACHE", str(tmp_path / "cache"))
    monkeypatch.chdir(tmp_path)
    (tmp_path / "r.txt").write_text("1 1\n12 0.3\n")
    assert main(["simulate", "--world", str(folder / "building.ply"), "--route", "r.txt", "--out", "seq"]) == 2
    err = capsys.readouterr().err
    assert "waypoint 1 (12.00, 0.30) is not on free floor" in err and "the nearest free point is" in err
    assert main(["simulate", "--world", "university", "--floor", "0.5", "--route", "demo", "--out", "seq"]) == 2
    assert "--floor describes a mesh file, not the world 'university'" in capsys.readouterr().err
    assert main(["simulate", "--world", str(folder / "building.ply"), "--route", "demo", "--out", "seq"]) == 2
    assert "route 'demo' is a route of world 'university'" in capsys.readouterr().err
    assert main(["simulate", "--world", "h.ply", "--route", "demo", "--out", "seq"]) == 2
    assert "--world: mesh file" in capsys.readouterr().err
    assert not (tmp_path / "seq").exists()
    (tmp_path / "ok.txt").write_text("1 1\n3 1\n")
    args = ["simulate", "--world", str(folder / "building.glb"), "--floor", "0", "--route", "ok.txt", "--out", "seq",
            "--width", "32", "--height", "24"]
    assert main(args) == 0
    assert "route ok in world building" in capsys.readouterr().out
    assert main(["world", "--mesh", str(folder / "building.ply"), "--route", "ok.txt", "--out", "plan.png"]) == 0
    assert (tmp_path / "plan.png").is_file()


def test_study_world_is_a_mesh_relative_to_the_study_file(folder, tmp_path):
    study = tmp_path / "s.toml"
    shutil.copy(folder / "building.ply", tmp_path / "b.ply")
    (tmp_path / "r.txt").write_text("1 1\n8.5 2.6\n")
    study.write_text('world = "b.ply"\nroutes = ["r.txt"]\nnoise = ["small"]\nmethods = ["odometry"]\nseeds = [0, 3]\n')
    config = load_study(study, ["odometry"])
    assert MeshSpec.from_ref(config.world).path == str(tmp_path / "b.ply")
    runs = plan_runs(config)
    assert len(runs) == 2 and all(r.world == config.world and r.route_object().world == config.world for r in runs)
    study.write_text('world = { mesh = "b.ply", floor = 0.0, units = "m" }\nroutes = ["r.txt"]\nnoise = ["small"]\n'
                     'methods = ["odometry"]\nseeds = 1\n')
    assert MeshSpec.from_ref(load_study(study, ["odometry"]).world).floor == 0.0
    for world, message in (
        ('"nowhere.glb"', r"study file .*s.toml: world: mesh file .*nowhere.glb does not exist"),
        ('{ mesh = "b.ply", units = "feet" }', r"s.toml: world: unknown units 'feet'"),
        ('"b.ply"\nroutes = ["demo"]', r"routes\[0\]: route 'demo' is in world 'university', the study in 'b.ply'"),
    ):
        text = f"world = {world}\n" + ("" if "routes" in world else 'routes = ["r.txt"]\n')
        study.write_text(text + 'noise = ["small"]\nmethods = ["odometry"]\nseeds = 1\n')
        with pytest.raises(StudyConfigError, match=message):
            load_study(study, ["odometry"])


def test_a_scene_of_textured_and_coloured_parts_becomes_one_textured_mesh(tmp_path):
    from PIL import Image

    from longslam.world.mesh_reader import read_mesh_file

    image = np.zeros((4, 4, 3), np.uint8)
    image[:2, :2], image[:2, 2:], image[2:, :2], image[2:, 2:] = (255, 0, 0), (0, 255, 0), (0, 0, 255), (255, 255, 0)
    # A factor of 1: trimesh would otherwise write its default diffuse, 0.4, which glTF multiplies in.
    material = trimesh.visual.material.PBRMaterial(baseColorTexture=Image.fromarray(image), baseColorFactor=[255, 255, 255, 255])
    visual = trimesh.visual.TextureVisuals(uv=[[0, 0], [1, 0], [1, 1], [0, 1]], material=material)
    quad = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]], visual=visual, process=False)
    box = trimesh.creation.box((1, 1, 1))
    box.visual.face_colors = np.tile([10, 200, 30, 255], (12, 1))
    scene = trimesh.Scene()
    scene.add_geometry(quad, node_name="quad")
    scene.add_geometry(box, node_name="box", transform=trimesh.transformations.translation_matrix((3.0, 0.0, 0.0)))
    scene.export(tmp_path / "mix.glb")
    mesh = read_mesh_file(tmp_path / "mix.glb")
    assert mesh.is_textured and len(mesh.triangles) == 14
    # The node's transform is applied: the box is centred on x = 3 (in the file's y-up axes).
    centres = mesh.vertices[mesh.triangles].mean(axis=1)
    on_box = centres[:, 0] > 2.0
    assert on_box.sum() == 12 and np.allclose(mesh.vertices[mesh.triangles[on_box]][..., 0].mean(), 3.0)
    # Each triangle's texels: the box's face colour, the quad's corner colours (uv v up: texel row 0 is v = 1).
    def texel(u, v):
        return tuple(mesh.texture[int(v), int(u)])
    box_uv = mesh.triangle_uvs[on_box].reshape(-1, 2)
    assert {texel(u, v) for u, v in box_uv} == {(10, 200, 30)}
    quad_uv = mesh.triangle_uvs[~on_box].mean(axis=1)  # each triangle's centre of texture
    # Corners (0, 0), (1, 0), (1, 1): the lower right half, centre (2/3, 1/3) -> the yellow quarter.
    assert texel(*quad_uv[0]) == (255, 255, 0)
    # Corners (0, 0), (1, 1), (0, 1): centre (1/3, 2/3) -> the red quarter.
    assert texel(*quad_uv[1]) == (255, 0, 0)
