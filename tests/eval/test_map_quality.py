"""Map quality: precision and recall of occupied cells within a tolerance; the walls the camera saw."""

from __future__ import annotations

import math

import numpy as np
import pytest

from longslam.eval.map_quality import map_quality, observed_walls
from longslam.core.gridmap import FREE, OCCUPIED, UNKNOWN, GridMap

RES = 0.05


def corridor(offset_rows: int = 0, shape=(120, 200), extra_rows: tuple[int, ...] = ()) -> GridMap:
    """A corridor: walls along rows 40 and 80 (y = 2 m and 4 m), free between, 10 m long."""
    data = np.full(shape, UNKNOWN, dtype=np.int8)
    data[41 + offset_rows:80 + offset_rows, 10:190] = FREE
    for row in (40, 80, *extra_rows):
        data[row + offset_rows, 10:190] = OCCUPIED
    return GridMap(data, RES, (0.0, 0.0))


def test_identical_maps_score_one():
    q = map_quality(corridor(), corridor())
    assert q["map_precision"] == 1.0 and q["map_recall"] == 1.0 and q["map_f1"] == 1.0
    assert q["map_tolerance_m"] == pytest.approx(2 * RES)
    assert q["map_occupied_cells"] == q["map_true_cells"] == 2 * 180


def test_a_shift_within_the_tolerance_is_forgiven_and_beyond_it_is_not():
    assert map_quality(corridor(2), corridor(), tolerance_cells=2)["map_precision"] == 1.0
    far = map_quality(corridor(3), corridor(), tolerance_cells=2)
    assert far["map_precision"] == 0.0 and far["map_recall"] == 0.0


def test_a_fake_corridor_costs_precision_not_recall():
    # The method drew the corridor twice, the copy 1 m off: half its walls are not in the world.
    doubled = corridor(extra_rows=(60, 100))
    q = map_quality(doubled, corridor())
    assert q["map_precision"] == pytest.approx(0.5) and q["map_recall"] == 1.0


def test_grids_of_other_resolution_and_origin_compare_in_world_coordinates():
    truth = corridor()
    coarse = np.full((30, 50), UNKNOWN, dtype=np.int8)  # 0.2 m cells
    coarse[10, 3:47] = OCCUPIED  # y in [2.0, 2.2): the wall at y = 2.0-2.05
    coarse[20, 3:47] = OCCUPIED  # y in [4.0, 4.2)
    q = map_quality(GridMap(coarse, 0.2, (0.0, 0.0)), truth, tolerance_cells=2)
    assert q["map_tolerance_m"] == pytest.approx(0.4)
    assert q["map_precision"] == 1.0 and q["map_recall"] > 0.9


def test_the_map_is_moved_by_the_trajectory_alignment():
    truth = corridor()
    # The estimate is the truth rotated by 90 degrees about the origin; the alignment undoes it.
    rotated_xy = np.argwhere(truth.data == OCCUPIED)[:, ::-1] * RES  # x, y of cell corners
    est = np.full((400, 400), UNKNOWN, dtype=np.int8)
    origin = (-10.0, -10.0)
    est_xy = np.column_stack([-rotated_xy[:, 1], rotated_xy[:, 0]]) + RES / 2 * np.array([-1, 1])
    cells = np.floor((est_xy - origin) / RES).astype(int)
    est[cells[:, 1], cells[:, 0]] = OCCUPIED
    estimate = GridMap(est, RES, origin)
    assert map_quality(estimate, truth)["map_precision"] < 0.1
    c, s = math.cos(-math.pi / 2), math.sin(-math.pi / 2)
    back = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    assert map_quality(estimate, truth, rotation=back, translation=np.zeros(3))["map_precision"] > 0.95


def test_no_occupied_cells():
    empty = GridMap(np.full((10, 10), FREE, dtype=np.int8), RES, (0.0, 0.0))
    q = map_quality(empty, corridor())
    assert q["map_precision"] is None and q["map_recall"] == 0.0 and q["map_f1"] is None


def test_observed_walls_are_the_first_hit_within_range_and_field_of_view():
    truth = corridor(extra_rows=(20,))  # a third wall behind the lower one
    # At x = 2 m in the middle of the corridor, looking down (-y): the wall at y = 2 m is seen,
    # the wall behind it at y = 1 m is not, nor the wall at y = 4 m behind the camera.
    mask = observed_walls(truth, np.array([[2.0, 3.0, -math.pi / 2]]), hfov_deg=90.0, max_range=8.0)
    rows = set(np.argwhere(mask)[:, 0])
    assert rows == {40}
    cols = np.argwhere(mask)[:, 1]
    assert 18 <= cols.min() and cols.max() <= 62  # +-45 degrees over 1 m: x in [1, 3] m
    # Recall over what was seen: a map of only that stretch of wall has recall 1.
    seen_only = GridMap(np.where(mask, OCCUPIED, FREE).astype(np.int8), RES, (0.0, 0.0))
    q = map_quality(seen_only, truth, observed=mask)
    assert q["map_recall"] == 1.0 and q["map_precision"] == 1.0
    assert map_quality(seen_only, truth)["map_recall"] < 0.2
    # Out of range: nothing seen.
    assert not observed_walls(truth, np.array([[2.0, 3.0, -math.pi / 2]]), max_range=0.5).any()
