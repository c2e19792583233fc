"""The simulated RGB-D camera."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from longslam.core.errors import InputError
from longslam.core.geometry import camera_poses_from_planar
from longslam.sim.camera import CameraSettings, RGBDCamera
from longslam.world import get_world


@pytest.fixture(scope="module")
def world():
    return get_world("university")


@pytest.fixture(scope="module")
def camera(world):
    return RGBDCamera(world.mesh, nthreads=1)


def pose_at(x: float, y: float, yaw: float, height: float = 1.25) -> np.ndarray:
    return camera_poses_from_planar(np.array([[x, y, yaw]]), height)[0]


def orb_count(rgb: np.ndarray) -> int:
    return len(cv2.ORB_create(500).detect(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY), None))


def test_settings_defaults_and_intrinsics():
    s = CameraSettings()
    assert (s.width, s.height, s.hfov_deg, s.max_depth, s.camera_height) == (320, 240, 90.0, 8.0, 1.25)
    k = s.intrinsics
    assert (k.width, k.height, k.cx, k.cy) == (320, 240, 160.0, 120.0)
    assert k.fx == pytest.approx(160.0) and k.fy == pytest.approx(160.0)


@pytest.mark.parametrize("field, value", [
    ("width", 0), ("height", -5), ("width", 320.5), ("hfov_deg", 180.0), ("hfov_deg", 0.0),
    ("max_depth", -1.0), ("max_depth", math.inf), ("camera_height", 0.0), ("camera_height", math.nan),
])
def test_settings_validation_names_the_field(field, value):
    with pytest.raises(InputError, match=field):
        CameraSettings(**{field: value})


def test_output_types(camera):
    rgb, depth = camera.render(pose_at(20.0, 31.25, 0.0))
    assert rgb.shape == (240, 320, 3) and rgb.dtype == np.uint8
    assert depth.shape == (240, 320) and depth.dtype == np.float32
    with pytest.raises(InputError):
        camera.render(np.eye(3))


def test_depth_of_a_wall_straight_ahead(camera):
    # In the spine (y from 30 to 32.5) looking along +y: the north wall fills the view at 1.25 m.
    # Depth is camera-frame z, so a wall square to the optical axis reads 1.25 at every pixel.
    _, depth = camera.render(pose_at(20.0, 31.25, math.pi / 2))
    assert depth[120, 160] == pytest.approx(1.25, abs=1e-5)
    assert np.allclose(depth, 1.25, atol=1e-4)


def test_depth_matches_ray_plane_intersection(camera):
    # In the hall, 5 m from its east wall (x = 129), turned 0.2 rad off the wall's normal.
    pose = pose_at(124.0, 31.0, 0.2)
    _, depth = camera.render(pose)
    k = camera.intrinsics
    u, v = np.meshgrid(np.arange(k.width), np.arange(k.height))
    dirs = np.stack([(u - k.cx) / k.fx, (v - k.cy) / k.fy, np.ones(u.shape)], axis=-1) @ pose[:3, :3].T
    t = (129.0 - pose[0, 3]) / dirs[..., 0]  # z = 1 along the camera axis, so t is the depth
    hit = pose[:3, 3] + t[..., None] * dirs
    on_wall = (hit[..., 1] > 19.1) & (hit[..., 1] < 42.9) & (hit[..., 2] > 0.05) & (hit[..., 2] < 2.95) & (t < 7.9)
    assert on_wall.sum() > 20000
    assert np.allclose(depth[on_wall], t[on_wall], atol=1e-4)


def test_depth_back_projects_onto_the_corridor(camera):
    pose = pose_at(16.0, 31.0, 0.1)  # no door or junction within 8 m ahead
    _, depth = camera.render(pose)
    k = camera.intrinsics
    v, u = np.nonzero(depth)
    z = depth[v, u]
    pts_cam = np.column_stack([(u - k.cx) / k.fx * z, (v - k.cy) / k.fy * z, z])
    pts = pts_cam @ pose[:3, :3].T + pose[:3, 3]
    assert np.all((pts[:, 1] > 30.0 - 1e-3) & (pts[:, 1] < 32.5 + 1e-3))  # inside the spine's walls
    assert np.all((pts[:, 2] > -1e-3) & (pts[:, 2] < 3.0 + 1e-3))


def test_depth_is_zero_beyond_max_depth(camera):
    # Down the 100 m spine: the far end is out of range, but its colour is still seen.
    rgb, depth = camera.render(pose_at(7.0, 31.25, 0.0))
    assert depth[120, 160] == 0.0
    assert depth.max() <= 8.0
    assert (depth == 0).mean() > 0.01
    assert rgb[120, 160].sum() > 0


def test_images_have_features(camera):
    corridor, _ = camera.render(pose_at(20.0, 31.25, 0.0))
    hall, _ = camera.render(pose_at(117.0, 31.0, 2.5))
    classroom, _ = camera.render(pose_at(45.0, 33.5, 1.2))
    for rgb in (corridor, hall, classroom):
        assert orb_count(rgb) > 100
        assert rgb.std() > 20  # real contrast, not a flat image


def test_walls_at_different_angles_are_shaded_differently(camera):
    # The corner where the spine's north wall meets branch a's west wall (x = 28, y = 32.5).
    rgb, depth = camera.render(pose_at(26.5, 31.0, math.pi / 4))
    left, right = rgb[100:140, 40:80].astype(float), rgb[100:140, 240:280].astype(float)
    assert abs(np.median(left) - np.median(right)) > 3


def test_lookalike_panels_look_alike_and_others_differ(camera):
    # x = 20 and x = 76 are at the same offset in the two look-alike stretches of the spine.
    a, _ = camera.render(pose_at(20.0, 31.25, math.pi / 2))
    b, _ = camera.render(pose_at(76.0, 31.25, math.pi / 2))
    c, _ = camera.render(pose_at(40.0, 31.25, -math.pi / 2))  # an ordinary stretch, south wall
    d, _ = camera.render(pose_at(98.0, 31.25, -math.pi / 2))

    def diff(x, y):
        return np.abs(x.astype(float) - y.astype(float)).mean()

    assert diff(a, b) < 1.0
    assert diff(c, d) > 10.0 and diff(a, c) > 10.0


def test_render_is_deterministic(world, camera):
    pose = pose_at(60.0, 31.0, 0.7)
    rgb1, depth1 = camera.render(pose)
    rgb2, depth2 = RGBDCamera(world.mesh, CameraSettings()).render(pose)
    assert np.array_equal(rgb1, rgb2) and np.array_equal(depth1, depth2)


def test_settings_change_the_image(world):
    settings = CameraSettings(width=160, height=120, hfov_deg=60.0, max_depth=3.0)
    rgb, depth = RGBDCamera(world.mesh, settings).render(pose_at(20.0, 31.25, 0.0))
    assert rgb.shape == (120, 160, 3) and depth.shape == (120, 160)
    assert depth.max() <= 3.0 and (depth == 0).any()
