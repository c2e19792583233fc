"""The world: textured mesh of the floor plan, registry, external meshes."""

from __future__ import annotations

import json
import struct

import numpy as np
import open3d as o3d
import pytest

from longslam.core.errors import InputError, UnknownNameError
from longslam.core.geometry import camera_poses_from_planar
from longslam.core.gridmap import FREE, OCCUPIED
from longslam.sim.camera import RGBDCamera
from longslam.world import WORLDS, build_mesh, get_world, load_mesh_world
from longslam.world.builder import JAMB, wall_segments
from longslam.world.layout import Box, FloorPlan, Rect
from longslam.world.textures import floor_tiles, pack_atlas, wall_panel


@pytest.fixture(scope="module")
def world():
    return get_world("university")


def _small_plan() -> FloorPlan:
    """Two rooms joined by a door, a table: small enough to build in a blink."""
    return FloorPlan(
        name="two_rooms",
        bounds=(0.0, 0.0, 12.0, 6.0),
        free=[Rect(0.5, 0.5, 5.5, 5.5, "room", "a"), Rect(5.7, 0.5, 11.5, 5.5, "hall", "b"),
              Rect(5.5, 2.0, 5.7, 3.0, "door", "door")],
        furniture=[Box(2.0, 2.0, 3.0, 2.6, 0.75, "table")],
        places={"a": (2.0, 4.0), "b": (8.0, 3.0)},
    )


def _vertical_triangles(mesh):
    tri = mesh.vertices[mesh.triangles]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    vertical = np.abs(normal[:, 2]) < 1e-9
    return tri.mean(axis=1)[vertical], normal[vertical], np.flatnonzero(vertical)


def test_university_world_parts(world):
    plan = world.plan
    assert world.name == "university" and world.floor_z == 0.0
    assert world.places == plan.places
    assert world.occupancy.resolution == 0.05
    assert np.all(world.occupancy.values_at(np.array(list(world.places.values()))) == FREE)
    mesh = world.mesh
    assert mesh.vertices.dtype == np.float64 and mesh.triangles.dtype == np.int32
    assert mesh.triangle_uvs.shape == (len(mesh.triangles), 3, 2) and mesh.triangle_uvs.dtype == np.float32
    assert mesh.texture.dtype == np.uint8 and mesh.texture.ndim == 3
    assert mesh.nbytes < 100e6
    h, w = mesh.texture.shape[:2]
    assert mesh.triangle_uvs[..., 0].min() >= 0 and mesh.triangle_uvs[..., 0].max() <= w
    assert mesh.triangle_uvs[..., 1].min() >= 0 and mesh.triangle_uvs[..., 1].max() <= h
    lo, hi = mesh.bounds
    assert lo[2] == 0.0 and hi[2] == plan.wall_height


def test_get_world_is_cached_and_names_are_checked(world):
    assert get_world("university") is world
    assert "university" in WORLDS
    with pytest.raises(UnknownNameError, match="university"):
        get_world("no_such_building")


def test_mesh_is_deterministic_for_a_seed():
    plan = _small_plan()
    a, b, c = build_mesh(plan, seed=3), build_mesh(plan, seed=3), build_mesh(plan, seed=4)
    assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.triangles, b.triangles)
    assert np.array_equal(a.triangle_uvs, b.triangle_uvs) and np.array_equal(a.texture, b.texture)
    assert np.array_equal(a.vertices, c.vertices)  # the seed changes the look, not the geometry
    assert not np.array_equal(a.texture, c.texture)


def test_wall_faces_face_free_space(world):
    plan = world.plan
    free = plan.free_mask(0.05)
    centre, normal, _ = _vertical_triangles(world.mesh)
    on_furniture = np.zeros(len(centre), dtype=bool)
    for b in plan.furniture:
        on_furniture |= ((centre[:, 0] >= b.xmin - 1e-6) & (centre[:, 0] <= b.xmax + 1e-6)
                         & (centre[:, 1] >= b.ymin - 1e-6) & (centre[:, 1] <= b.ymax + 1e-6))
    front = world.occupancy.world_to_cell(centre[:, :2] + 0.02 * normal[:, :2])
    back = world.occupancy.world_to_cell(centre[:, :2] - 0.02 * normal[:, :2])
    assert np.all(free[front[:, 0], front[:, 1]])
    walls = ~on_furniture
    assert walls.sum() > 100
    assert not np.any(free[back[walls, 0], back[walls, 1]])


def test_wall_segments_of_a_square_room():
    free = np.zeros((10, 10), dtype=bool)
    free[2:8, 3:6] = True  # x in [0.3, 0.6), y in [0.2, 0.8) at 0.1 m cells
    segs = wall_segments(free, (0.0, 0.0), 0.1)
    assert len(segs) == 4
    by_side = {(s.axis, s.normal_sign): s for s in segs}
    bottom, top = by_side[(0, 1)], by_side[(0, -1)]  # walls along x: free above / below them
    assert bottom.fixed == pytest.approx(0.2) and top.fixed == pytest.approx(0.8)
    assert (bottom.start, bottom.end) == pytest.approx((0.3, 0.6))
    left, right = by_side[(1, 1)], by_side[(1, -1)]
    assert left.fixed == pytest.approx(0.3) and right.fixed == pytest.approx(0.6)
    assert (left.start, left.end) == pytest.approx((0.2, 0.8))


def test_floor_and_ceiling_cover_free_space(world):
    rng = np.random.default_rng(0)
    rows, cols = np.nonzero(world.occupancy.data == FREE)
    pick = rng.choice(len(rows), 500, replace=False)
    xy = world.occupancy.cell_to_world(np.column_stack([rows[pick], cols[pick]]))
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(world.mesh.vertices.astype(np.float32)),
                        o3d.core.Tensor(world.mesh.triangles.astype(np.uint32)))
    rays = np.zeros((2 * len(xy), 6), dtype=np.float32)
    rays[:, :2] = np.vstack([xy, xy])
    rays[:, 2] = 0.5
    rays[: len(xy), 5], rays[len(xy) :, 5] = -1.0, 1.0
    t = scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
    down, up = t[: len(xy)], t[len(xy) :]
    assert np.allclose(down, 0.5, atol=1e-5)  # the floor at z = 0 everywhere
    assert np.allclose(up, 2.5, atol=1e-5)  # the ceiling at 3 m (free cells are not under furniture)


def test_door_jambs_share_the_door_texture(world):
    mesh = world.mesh
    centre, normal, idx = _vertical_triangles(mesh)
    tri = mesh.vertices[mesh.triangles[idx]]
    width = np.ptp(tri[:, :, :2], axis=1).max(axis=1)  # horizontal extent of each triangle
    jamb = width < JAMB - 1e-6
    assert jamb.sum() >= 2 * 2 * 8  # 8 doors, 2 jambs each, 2 triangles per jamb
    # All of them sample one narrow strip of the atlas.
    u = mesh.triangle_uvs[idx[jamb], :, 0]
    assert np.ptp(u) < JAMB * 50 + 1


def test_textures_are_deterministic_and_packed_without_overlap():
    a = wall_panel(np.random.default_rng(5), 3.2, 3.0, (220, 220, 210))
    b = wall_panel(np.random.default_rng(5), 3.2, 3.0, (220, 220, 210))
    assert a.shape == (150, 160, 3) and np.array_equal(a, b)
    images = [a, floor_tiles(np.random.default_rng(1)), a[:40, :70], np.zeros((5, 3000, 3), np.uint8)]
    atlas = pack_atlas(images, width=400)
    covered = np.zeros(atlas.image.shape[:2], dtype=np.int32)
    for im, (u, v) in zip(images, atlas.offsets):
        assert np.array_equal(atlas.image[v : v + im.shape[0], u : u + im.shape[1]], im)
        covered[v : v + im.shape[0], u : u + im.shape[1]] += 1
    assert covered.max() == 1


# ---- external meshes --------------------------------------------------------------------------

def _box(x0, y0, z0, x1, y1, z1, colour):
    b = o3d.geometry.TriangleMesh.create_box(x1 - x0, y1 - y0, z1 - z0)
    b.translate((x0, y0, z0))
    b.paint_uniform_color(colour)
    return b


def _box_room(floor_z: float = 0.0) -> o3d.geometry.TriangleMesh:
    """A 6 x 4 m room with 0.2 m walls 3 m high, a table in it, floor at `floor_z`."""
    f = floor_z
    room = _box(0, 0, f - 0.1, 6, 4, f, (0.6, 0.5, 0.4))
    for part in (
        _box(-0.2, 0, f, 0, 4, f + 3, (0.8, 0.2, 0.2)), _box(6, 0, f, 6.2, 4, f + 3, (0.2, 0.8, 0.2)),
        _box(-0.2, -0.2, f, 6.2, 0, f + 3, (0.2, 0.2, 0.8)), _box(-0.2, 4, f, 6.2, 4.2, f + 3, (0.8, 0.8, 0.2)),
        _box(2, 1.5, f, 3, 2.5, f + 0.75, (0.3, 0.3, 0.3)),
    ):
        room += part
    return room


def test_external_mesh_round_trip(tmp_path):
    path = tmp_path / "room.ply"
    assert o3d.io.write_triangle_mesh(str(path), _box_room(floor_z=1.0))
    world = load_mesh_world(path, floor_z=1.0)
    # The world is moved so that its floor is the plane z = 0 the robot drives on.
    assert world.name == "room" and world.floor_z == 0.0 and world.places == {} and world.plan is None
    assert world.mesh.bounds[0][2] == pytest.approx(-0.1) and world.mesh.bounds[1][2] == pytest.approx(3.0)
    # Found without being told: the slab's top, not its underside or the table.
    assert load_mesh_world(path).mesh.bounds[0][2] == pytest.approx(-0.1)
    assert world.mesh.vertex_colors is not None and not world.mesh.is_textured
    grid = world.occupancy
    assert grid.resolution == 0.05
    inside = np.array([[1.0, 1.0], [5.0, 3.0], [4.0, 0.5]])
    walls = np.array([[0.02, 2.0], [5.99, 2.0], [3.0, 0.02], [3.0, 3.99]])
    outside = np.array([[-0.1, 2.0], [6.1, 2.0]])  # inside the solid walls
    assert np.all(grid.values_at(inside) == FREE)
    assert np.all(grid.values_at(walls) == OCCUPIED)
    assert np.all(grid.values_at(np.array([[2.5, 2.0]])) == OCCUPIED)  # the table
    assert np.all(grid.values_at(outside) != FREE)

    camera = RGBDCamera(world.mesh)
    pose = camera_poses_from_planar(np.array([[1.0, 2.0, 0.0]]), 1.25)[0]
    rgb, depth = camera.render(pose)
    assert depth[120, 160] == pytest.approx(5.0, abs=1e-4)  # the green wall at x = 6
    assert rgb[120, 160, 1] > 100 and rgb[120, 160, 0] < 80


def _write_glb(path, mesh: o3d.geometry.TriangleMesh) -> None:
    """A minimal binary glTF with positions, vertex colours and indices, y up as glTF wants it
    (Open3D's own GLB writer writes files its reader rejects)."""
    z_up = np.asarray(mesh.vertices)
    vertices = np.column_stack([z_up[:, 0], z_up[:, 2], -z_up[:, 1]]).astype(np.float32)
    parts = [vertices.tobytes(), np.asarray(mesh.vertex_colors, np.float32).tobytes(),
             np.asarray(mesh.triangles, np.uint32).tobytes()]
    offsets = np.cumsum([0] + [len(p) for p in parts])
    binary = b"".join(parts)
    n = len(vertices)
    gltf = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "COLOR_0": 1}, "indices": 2}]}],
        "buffers": [{"byteLength": len(binary)}],
        "bufferViews": [{"buffer": 0, "byteOffset": int(o), "byteLength": len(p)} for o, p in zip(offsets, parts)],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": n, "type": "VEC3",
             "min": vertices.min(0).tolist(), "max": vertices.max(0).tolist()},
            {"bufferView": 1, "componentType": 5126, "count": n, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5125, "count": 3 * len(mesh.triangles), "type": "SCALAR"},
        ],
    }
    js = json.dumps(gltf).encode()
    js += b" " * (-len(js) % 4)
    binary += b"\0" * (-len(binary) % 4)
    with open(path, "wb") as f:
        f.write(struct.pack("<III", 0x46546C67, 2, 28 + len(js) + len(binary)))
        f.write(struct.pack("<II", len(js), 0x4E4F534A) + js)
        f.write(struct.pack("<II", len(binary), 0x004E4942) + binary)


def test_external_glb(tmp_path):
    path = tmp_path / "room.glb"
    _write_glb(path, _box_room())
    world = load_mesh_world(path, name="my_room")
    assert world.name == "my_room" and world.mesh.vertex_colors is not None
    assert np.all(world.occupancy.values_at(np.array([[1.0, 1.0], [0.02, 2.0]])) == [FREE, OCCUPIED])


def test_external_textured_obj_renders_like_the_original(tmp_path):
    mesh = build_mesh(_small_plan(), seed=0)
    path = tmp_path / "two_rooms.obj"
    assert o3d.io.write_triangle_mesh(str(path), mesh.to_open3d())
    world = load_mesh_world(path)
    assert world.mesh.is_textured
    pose = camera_poses_from_planar(np.array([[3.0, 3.0, 0.4]]), 1.25)[0]
    rgb_a, depth_a = RGBDCamera(mesh).render(pose)
    rgb_b, depth_b = RGBDCamera(world.mesh).render(pose)
    assert np.allclose(depth_a, depth_b, atol=1e-4)
    # The same texels, but for the odd pixel on a texel edge after the round trip through [0, 1].
    assert np.mean(np.abs(rgb_a.astype(int) - rgb_b.astype(int)).max(axis=2) > 0) < 0.02


def test_external_mesh_errors_name_the_file(tmp_path):
    missing = tmp_path / "nowhere.ply"
    with pytest.raises(InputError, match="nowhere.ply"):
        load_mesh_world(missing)
    junk = tmp_path / "junk.ply"
    junk.write_text("this is not a mesh\n")
    with pytest.raises(InputError, match="junk.ply"):
        load_mesh_world(junk)
    points_only = tmp_path / "points.ply"
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.random.default_rng(0).random((10, 3))))
    o3d.io.write_point_cloud(str(points_only), pcd)
    with pytest.raises(InputError, match="points.ply.*no triangles"):
        load_mesh_world(points_only)
    room = tmp_path / "room.ply"
    o3d.io.write_triangle_mesh(str(room), _box_room())
    with pytest.raises(InputError, match="room.ply.*floor height 5.0"):
        load_mesh_world(room, floor_z=5.0)
