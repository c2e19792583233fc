"""The diagnosis of a run's error: parts along the route, stretches, loops against the truth."""

from __future__ import annotations

import numpy as np
import pytest

from longslam.eval.diagnose import error_parts, loop_errors, regions_of, stretches, worst_stretches
from longslam.world.layout import Rect


def _straight(n: int = 201, step: float = 0.1) -> np.ndarray:
    return np.column_stack([step * np.arange(n), np.zeros(n), np.zeros(n)])


def test_a_heading_error_becomes_across_track_error_and_nothing_along():
    truth = _straight()
    estimate = truth.copy()
    estimate[:, 2] = np.radians(1.0)  # one degree off from the start, driving the same distances
    estimate[:, 0] = truth[:, 0] * np.cos(np.radians(1.0))
    estimate[:, 1] = truth[:, 0] * np.sin(np.radians(1.0))
    parts = error_parts(truth, estimate)
    assert np.allclose(parts.heading_deg, 1.0)
    assert parts.distance_m[-1] == pytest.approx(20.0)
    assert parts.across_m[-1] == pytest.approx(20.0 * np.sin(np.radians(1.0)), rel=1e-9)
    assert abs(parts.along_m[-1]) < 0.01  # 20 (1 - cos 1 deg) = 3 mm behind


def test_along_and_across_follow_the_truths_heading_not_the_world_axes():
    truth = np.column_stack([np.zeros(5), np.arange(5.0), np.full(5, np.pi / 2)])  # driving +y
    estimate = truth + np.array([-0.2, 0.3, 0.0])  # 0.3 m ahead, 0.2 m to the left of +y
    parts = error_parts(truth, estimate)
    assert np.allclose(parts.along_m, 0.3) and np.allclose(parts.across_m, 0.2)


def test_loop_errors_against_the_truths_relative_pose():
    truth = _straight(11, 1.0)
    right = [0, 10, 10.0, 0.0, 0.0]
    off = [2, 8, 6.0, 0.6, np.radians(1.0)]
    turned = [3, 9, 6.0, 0.0, np.radians(8.0)]
    found = loop_errors(truth, np.array([right, off, turned]))
    assert [(lp.frame_i, lp.frame_j) for lp in found] == [(0, 10), (2, 8), (3, 9)]
    assert found[0].error_m == pytest.approx(0.0) and not found[0].wrong
    assert found[1].error_m == pytest.approx(0.6) and found[1].wrong
    assert found[2].error_deg == pytest.approx(8.0) and found[2].wrong


def test_a_loop_is_not_wrong_along_a_direction_it_leaves_free():
    truth = _straight(11, 1.0)
    # 0.8 m off along x: wrong if it holds x (sigmas 0.05 m), not if it leaves x free (100 m).
    held = np.diag([400.0, 400.0, 2500.0])
    free = np.diag([1e-4, 400.0, 2500.0])
    upper = np.triu_indices(3)
    rows = np.array([[2, 8, 6.8, 0.0, 0.0, *held[upper]], [2, 8, 6.8, 0.0, 0.0, *free[upper]],
                     [2, 8, 6.8, 0.6, 0.0, *free[upper]]])
    found = loop_errors(truth, rows)
    assert found[0].error_m == pytest.approx(0.8) and found[0].wrong
    assert found[1].error_m == pytest.approx(0.0, abs=1e-6) and not found[1].wrong
    assert found[2].error_m == pytest.approx(0.6) and found[2].wrong  # across: still its own
    # A turned constraint's free direction turns with it: j's frame, not i's.
    turned = np.array([[2, 8, 6.0, 0.0, np.radians(90.0), *free[upper]]])
    truth_turned = truth.copy()
    truth_turned[8, 2] = np.radians(90.0)
    truth_turned[8, 1] = 0.8  # 0.8 m off along i's y, which is j's x: free
    assert loop_errors(truth_turned, turned)[0].error_m == pytest.approx(0.0, abs=1e-6)


def test_stretches_name_what_they_picked_up_and_their_dominant_factor():
    truth = _straight(201, 0.1)  # 20 m
    estimate = truth.copy()
    estimate[120:, 2] = np.radians(2.0)  # the heading goes wrong at 12 m
    estimate[120:, 1] = (truth[120:, 0] - 12.0) * np.sin(np.radians(2.0))
    parts = error_parts(truth, estimate)
    n = len(truth)
    table = {"wheel": np.ones(n), "visual": np.r_[np.ones(50), np.zeros(n - 50)],
             "scan": np.r_[np.zeros(50), np.ones(50), -np.ones(n - 100)], "scan_shift_m": np.full(n, 0.001)}
    loops = loop_errors(truth, np.array([[160, 190, 3.0, 0.0, 0.0]]))
    found = stretches(parts, 5.0, ["corridor"] * 150 + ["hall"] * 51, table, loops)
    assert [(s.start_m, s.end_m) for s in found] == [(0, 5), (5, 10), (10, 15), (15, 20)]
    assert [s.dominant for s in found] == ["visual", "scans", "wheels", "loops"]
    assert [s.region for s in found] == ["corridor", "corridor", "corridor", "hall"]
    assert found[2].scan_refused_share == pytest.approx(1.0) and found[3].loops == 1
    assert found[0].heading_gain_deg == pytest.approx(0.0) and found[2].heading_gain_deg == pytest.approx(2.0)
    assert worst_stretches(found, "heading", 1) == [found[2]]
    assert worst_stretches(found, "across", 2)[0] in found[2:]


def test_without_a_front_end_table_the_factors_are_unknown():
    parts = error_parts(_straight(), _straight())
    found = stretches(parts, 50.0)
    assert len(found) == 1 and found[0].dominant == "" and found[0].scan_share is None
    with pytest.raises(ValueError, match="longer than 0"):
        stretches(parts, 0.0)


def test_regions_are_the_smallest_free_rectangle_and_doors_are_not_regions():
    rects = [Rect(0, 0, 10, 10, "hall", "hall"), Rect(2, 2, 4, 4, "room", "office"), Rect(10, 4, 10.2, 5, "door", "d")]
    assert regions_of(np.array([[1, 1], [3, 3], [10.1, 4.5], [20, 20]]), rects) == ["hall", "office", "", ""]
