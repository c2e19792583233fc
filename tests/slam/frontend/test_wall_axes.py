"""The walls' directions as a heading reference (slam/frontend/wall_axes.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from longslam.core.errors import InputError
from longslam.core.geometry import compose_xyyaw as compose, relative_xyyaw as relative
from longslam.slam.frontend.filter import MotionNoise
from longslam.slam.frontend.smoother import FullSmoother, SmootherConfig
from longslam.core.geometry import fold_quarter as fold
from longslam.slam.frontend.wall_axes import WallAxes, WallAxesConfig, wall_direction
from longslam.slam.graph.factors import WheelStep


def _rotated(points: np.ndarray, degrees: float) -> np.ndarray:
    a = math.radians(degrees)
    return points @ np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]).T


def _corridor_corner(rng: np.random.Generator, noise: float = 0.003) -> np.ndarray:
    """A corridor's two walls and the wall at its end, as a scan (5 cm apart)."""
    left = np.column_stack([np.arange(0.5, 4.0, 0.05), np.full(70, 1.0)])
    right = np.column_stack([np.arange(0.5, 4.0, 0.05), np.full(70, -1.0)])
    end = np.column_stack([np.full(40, 4.0), np.arange(-1.0, 1.0, 0.05)])
    return np.vstack([left, right, end]) + rng.normal(0, noise, (180, 2))


@pytest.mark.parametrize("degrees", [-44.0, -12.5, 0.0, 7.0, 30.0, 44.0])
def test_wall_direction_is_the_walls_angle_modulo_90_degrees(degrees):
    found = wall_direction(_rotated(_corridor_corner(np.random.default_rng(1)), degrees))
    assert found is not None
    assert math.degrees(float(fold(found[0] - math.radians(degrees)))) == pytest.approx(0.0, abs=0.2)
    assert found[1] >= 150  # nearly every point lies along one of the two directions


def test_no_direction_in_scattered_points_or_too_few():
    rng = np.random.default_rng(2)
    assert wall_direction(rng.uniform(-3, 3, (300, 2))) is None
    assert wall_direction(_corridor_corner(rng)[:20]) is None


def test_a_round_room_has_no_dominant_direction():
    t = np.arange(0, 2 * math.pi, 0.02)  # a 3 m circle, 2 cm apart
    assert wall_direction(np.column_stack([3 * np.cos(t), 3 * np.sin(t)])) is None


def test_later_scans_turn_the_heading_onto_the_first_scans_axes():
    rng = np.random.default_rng(3)
    axes = WallAxes(WallAxesConfig(use=True, every=1, settle=1))
    scan = _corridor_corner(rng)
    [(frame, heading, direction)] = axes.measure(0, 0.0, scan)  # the first measurement sets the axes
    assert frame == 0 and abs(math.degrees(heading)) < 0.2 and abs(math.degrees(direction)) < 0.2
    # Facing world +y, with 1.5 degrees of heading error: the robot sees world-aligned walls
    # at -90 degrees (its scan depends on the truth alone) and believes they are at -88.5.
    truth_yaw, believed = math.radians(90.0), math.radians(91.5)
    seen = _rotated(_corridor_corner(rng), -90.0)
    [(frame, heading, direction)] = axes.measure(1, believed, seen)
    assert frame == 1 and abs(math.degrees(direction)) < 0.2  # the walls, in the robot's frame
    assert math.degrees(heading - truth_yaw) == pytest.approx(0.0, abs=0.2)


def test_the_axes_are_the_settling_measurements_mean_and_they_get_their_factors_then():
    rng = np.random.default_rng(6)
    axes = WallAxes(WallAxesConfig(use=True, every=1, settle=4))
    turns = [0.6, -0.4, 0.2, 30.0]  # three looks at the axes a little off, one at a 30-degree wing
    got = [axes.measure(k, 0.0, _rotated(_corridor_corner(rng), t)) for k, t in enumerate(turns)]
    assert got[:3] == [[], [], []]
    assert math.degrees(axes.axes) == pytest.approx(np.mean(turns[:3]), abs=0.1)
    assert [k for k, _, _ in got[3]] == [0, 1, 2] and axes.gated == 1


def test_the_gate_widens_with_the_online_headings_std():
    rng = np.random.default_rng(7)
    axes = WallAxes(WallAxesConfig(use=True, every=1, settle=1))
    axes.measure(0, 0.0, _corridor_corner(rng))
    turned = _rotated(_corridor_corner(rng), -6.0)  # the heading 6 degrees off
    assert axes.measure(1, 0.0, turned) == []  # outside the 3-degree gate
    assert len(axes.measure(2, 0.0, turned, yaw_std=math.radians(1.5))) == 1  # 3 + 3 x 1.5 degrees
    wing = _rotated(_corridor_corner(rng), 30.0)
    assert axes.measure(3, 0.0, wing, yaw_std=math.radians(20.0)) == []  # never past max_gate_deg


def test_a_wing_at_30_degrees_gives_no_heading():
    rng = np.random.default_rng(4)
    axes = WallAxes(WallAxesConfig(use=True, every=1, settle=1))
    axes.measure(0, 0.0, _corridor_corner(rng))
    assert axes.measure(1, 0.0, _rotated(_corridor_corner(rng), 30.0)) == []
    assert axes.gated == 1 and axes.measured == 2


def test_only_every_nth_frame_measures():
    rng = np.random.default_rng(5)
    axes = WallAxes(WallAxesConfig(use=True, every=10))
    assert axes.measure(3, 0.0, _corridor_corner(rng)) == [] and axes.measured == 0
    axes.measure(10, 0.0, _corridor_corner(rng))
    assert axes.measured == 1


@pytest.mark.parametrize("field, value", [("every", 0), ("sigma_deg", 0.0), ("gate_deg", 20.0), ("settle", 0)])
def test_bad_settings_are_refused(field, value):
    with pytest.raises(InputError, match=f"wall_axes.{field}"):
        WallAxesConfig(**{field: value})


def test_walls_along_the_axes_undo_a_wheel_heading_bias_in_the_smoother():
    """Wheels that turn 0.02 degrees a frame too much along a straight line: the smoother alone
    follows them (nothing tells their yaw bias apart from a turn); with the walls seen straight
    ahead every 10 frames, along axes it solves for from a wrong first value (2 degrees), it
    finds the bias and the end heading is the truth's."""
    frames = 300
    truth = np.array([[0.1 * k, 0.0, 0.0] for k in range(frames)])

    def solved(headings: bool) -> np.ndarray:
        smoother = FullSmoother(MotionNoise(), SmootherConfig(relative_tolerance=1e-9, iterations=50))
        online = truth[0].copy()
        for k in range(frames):
            wheel = sigmas = None
            if k:
                step = relative(truth[k - 1], truth[k]) + np.array([0.0, 0.0, math.radians(0.02)])
                wheel, sigmas = WheelStep(*step, True), np.array([0.002, 1e-3, 0.0006])
                online = compose(online, step)
            smoother.add_frame(online.copy(), wheel, sigmas, None, None, np.zeros(2))
            if headings and k % 10 == 0:
                smoother.add_wall(k, 0.0, math.radians(1.0))
        smoother.axes_initial = math.radians(2.0)
        return smoother.solve()

    free, held = solved(False), solved(True)
    assert math.degrees(free[-1, 2]) == pytest.approx(0.02 * (frames - 1), rel=0.05)
    assert abs(math.degrees(held[-1, 2])) < 0.5
    assert np.abs(held[:, 1]).max() < 0.25 * np.abs(free[:, 1]).max()
