"""The RGB-D step's heading refitted to its corners' bearings along the wheels' arc
(`visual_tracking.arc_fit`): a turn seen on exact depth."""

from __future__ import annotations

import math

import cv2
import numpy as np
from helpers.flat_walls import LOOK_ALONG_X, SETTINGS, K, _quads_mesh

from longslam.sim.camera import RGBDCamera
from longslam.slam.frontend.visual import VisualConfig, VisualOdometry, fit_arc_heading

# The camera looks along the base's x axis from the base's origin, 1.25 m up.
MOUNT = LOOK_ALONG_X.copy()
MOUNT[2, 3] = 1.25


def _room(rng: np.random.Generator) -> RGBDCamera:
    """A textured floor and three walls around a camera at the origin: corners at 1-5 m."""
    # Blotches a few centimetres across: texture finer than a pixel would flicker between frames.
    noise = cv2.GaussianBlur(rng.uniform(0.0, 255.0, (1024, 1024)), (0, 0), 3.0)
    grey = cv2.normalize(noise, None, 20, 235, cv2.NORM_MINMAX).astype(np.uint8)
    texture = grey[:, :, None].repeat(3, axis=2)
    floor = np.array([[-1, -6, 0], [7, -6, 0], [7, 6, 0], [-1, 6, 0]], float)
    ahead = np.array([[4.5, -6, 0], [4.5, 6, 0], [4.5, 6, 3], [4.5, -6, 3]], float)
    left = np.array([[-1, 2.5, 0], [7, 2.5, 0], [7, 2.5, 3], [-1, 2.5, 3]], float)
    right = np.array([[-1, -3.0, 0], [7, -3.0, 0], [7, -3.0, 3], [-1, -3.0, 3]], float)
    return RGBDCamera(_quads_mesh([floor, ahead, left, right], texture), SETTINGS, nthreads=1)


def _base(x: float, y: float, yaw: float) -> np.ndarray:
    pose = np.eye(4)
    pose[:2, :2] = [[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]]
    pose[:2, 3] = x, y
    return pose


def _heading_errors(arc_fit: bool, turns: list[float], wheel_error: float) -> list[float]:
    camera = _room(np.random.default_rng(11))
    errors = []
    for turn in turns:
        distance = 0.15
        step = np.array([distance * math.cos(turn / 2), distance * math.sin(turn / 2), turn])
        rgb0, d0 = camera.render(MOUNT)
        rgb1, d1 = camera.render(_base(*step) @ MOUNT)
        tracker = VisualOdometry(K, MOUNT, VisualConfig(arc_fit=arc_fit))
        tracker(rgb0, d0, np.zeros(3))
        wheels = step + np.array([0.0, 0.0, wheel_error])
        found = tracker(rgb1, d1, wheels)
        assert found is not None
        errors.append(abs(found.step[2] - turn))
        if arc_fit:  # on the arc: no sideways slip beyond the turn's own
            assert math.isclose(found.step[1], found.step[0] * math.tan(found.step[2] / 2), abs_tol=1e-9)
    return errors


def test_the_arc_fit_holds_a_turns_heading_better_than_the_planar_fit_of_3d_points():
    turns = [-0.06, -0.02, 0.0, 0.03, 0.08]  # up to 4.6 degrees in a step: a 10 px shift
    arc = _heading_errors(True, turns, wheel_error=0.005)
    planar = _heading_errors(False, turns, wheel_error=0.005)
    # The wheels' heading was 0.3 degrees off: the arc fit finds the turn to 0.01 degrees.
    assert max(arc) < 2e-4
    assert np.mean(arc) < 0.5 * np.mean(planar)


def test_without_wheels_the_step_is_not_put_on_an_arc():
    camera = _room(np.random.default_rng(11))
    rgb0, d0 = camera.render(MOUNT)
    sideways = np.array([0.02, 0.05, 0.0])  # a step no wheel makes: 5 cm to the side
    rgb1, d1 = camera.render(_base(*sideways) @ MOUNT)
    tracker = VisualOdometry(K, MOUNT, VisualConfig(arc_fit=True))
    tracker(rgb0, d0, None)
    found = tracker(rgb1, d1, None)
    assert found is not None
    np.testing.assert_allclose(found.step, sideways, atol=0.01)


def _arc_projection(distance: float):
    """Pixels of base-frame points (N, 4, homogeneous) seen after a step of `distance` along the arc of a turn."""
    to_camera = np.linalg.inv(MOUNT)

    def project(points: np.ndarray, yaw: float) -> np.ndarray:
        step = _base(distance * math.cos(yaw / 2), distance * math.sin(yaw / 2), yaw)
        q = points @ (to_camera @ np.linalg.inv(step)).T
        return np.column_stack([K.fx * q[:, 0] / q[:, 2] + K.cx, K.fy * q[:, 1] / q[:, 2] + K.cy])

    return project


def test_corners_locked_a_few_pixels_off_leave_the_arc_fit():
    rng = np.random.default_rng(5)
    n = 200
    points = np.column_stack(
        [rng.uniform(1.0, 5.0, n), rng.uniform(-2.0, 2.0, n), rng.uniform(0.0, 2.5, n), np.ones(n)]
    )
    project = _arc_projection(0.15)
    turn = 0.03
    seen = project(points, turn) + rng.normal(0.0, 0.1, (n, 2))
    # A sixth of the corners held by the next grout line, 4 pixels over, all the same way.
    seen[: n // 6, 0] += 4.0
    kept = fit_arc_heading(project, points, seen, 0.0, VisualConfig(arc_max_residual=0.0))
    left_out = fit_arc_heading(project, points, seen, 0.0, VisualConfig(arc_max_residual=1.5))
    assert kept is not None and left_out is not None
    assert abs(left_out - turn) < 1e-4
    assert abs(kept - turn) > 10 * abs(left_out - turn)
