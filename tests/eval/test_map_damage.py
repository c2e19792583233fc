"""Map drift versus map damage: the best planar alignment of a map, and doubled walls."""

from __future__ import annotations

import math

import numpy as np
import pytest

from longslam.core.errors import InputError
from longslam.core.gridmap import OCCUPIED, UNKNOWN, GridMap
from longslam.eval.doubled_walls import doubled_walls
from longslam.eval.map_align import align_map
from longslam.eval.map_quality import map_scores

RES = 0.05


def room() -> GridMap:
    """A 10 x 6 m room (walls two cells thick) with a partition from the bottom wall to y = 4 m:
    enough corners that only one (x, y, yaw) puts it on itself."""
    data = np.full((160, 240), UNKNOWN, np.int8)

    def wall(x0, x1, y0, y1):
        data[int(round(y0 / RES)):int(round(y1 / RES)), int(round(x0 / RES)):int(round(x1 / RES))] = OCCUPIED

    wall(1.0, 11.1, 1.0, 1.1)
    wall(1.0, 11.1, 7.0, 7.1)
    wall(1.0, 1.1, 1.0, 7.1)
    wall(11.0, 11.1, 1.0, 7.1)
    wall(6.0, 6.1, 1.0, 4.0)
    return GridMap(data, RES, (0.0, 0.0))


def from_points(xy: np.ndarray, like: GridMap) -> GridMap:
    """A map whose occupied cells hold the points, on `like`'s cells."""
    data = np.full(like.data.shape, UNKNOWN, np.int8)
    rc = like.world_to_cell(xy)
    ok = like.inside(rc)
    data[rc[ok, 0], rc[ok, 1]] = OCCUPIED
    return GridMap(data, like.resolution, like.origin)


def moved(truth: GridMap, x: float, y: float, yaw_deg: float) -> GridMap:
    """The truth's walls rotated by yaw about (6, 4) and shifted: a map that drifted as a whole."""
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    # Sample each wall cell finely so the rotated walls stay unbroken.
    walls = truth.occupied_points()
    fine = (walls[:, None, :] + np.stack(np.meshgrid([-0.02, 0.0, 0.02], [-0.02, 0.0, 0.02]), -1).reshape(1, -1, 2)).reshape(-1, 2)
    centre = np.array([6.0, 4.0])
    out = (fine - centre) @ np.array([[c, -s], [s, c]]).T + centre + (x, y)
    return from_points(out, truth)


def test_a_map_that_drifted_as_a_whole_scores_low_unaligned_and_high_aligned():
    truth = room()
    drifted = moved(truth, 0.7, -0.4, 3.0)
    q = map_scores(drifted, truth, 2.0, truth.data == OCCUPIED)
    assert q["map_precision"] < 0.3 and q["map_recall"] < 0.3
    assert q["map_precision_aligned"] > 0.95 and q["map_recall_aligned"] > 0.95
    x, y, yaw = q["map_alignment"]
    # Walls two cells thick, redrawn on the grid: the fit is good to a fraction of a degree.
    assert yaw == pytest.approx(-3.0, abs=0.5)
    # The inverse move of a point: (6.7, 3.6) (where (6, 4) went) comes back to (6, 4).
    c, s = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
    back = np.array([[c, -s], [s, c]]) @ np.array([6.7, 3.6]) + (x, y)
    assert np.allclose(back, (6.0, 4.0), atol=0.1)
    assert q["map_doubled_walls"] == 0.0


def test_a_doubled_wall_is_found_where_it_is_and_nowhere_else():
    truth = room()
    true_walls = truth.data == OCCUPIED
    assert doubled_walls(truth.occupied_points(), truth, true_walls, 0.1)[0] == 0.0

    # The top wall (y = 7 m) drawn again 1.2 m lower between x = 2 and 10 m: a fake corridor.
    copy = truth.occupied_points()
    copy = copy[(copy[:, 1] > 6.95) & (copy[:, 0] > 2.0) & (copy[:, 0] < 10.0)] - (0.0, 1.2)
    damaged = from_points(np.vstack([truth.occupied_points(), copy]), truth)
    q = map_scores(damaged, truth, 2.0, true_walls, with_places=True)
    places = q["map_doubled_places"]
    assert len(places) == q["map_doubled_wall_cells"] > 0
    assert np.all(np.abs(places[:, 1] - 7.05) < 0.1)  # only on the top wall
    assert places[:, 0].min() > 1.9 and places[:, 0].max() < 10.1
    # About the 8 m of the top wall (two rows of cells) out of all the room's wall cells.
    expected = 2 * 8.0 / RES / true_walls.sum()
    assert q["map_doubled_walls"] == pytest.approx(expected, rel=0.25)
    # The copy is not in the world: precision drops even after alignment; recall does not.
    assert q["map_precision_aligned"] < 0.85 and q["map_recall_aligned"] > 0.95


def test_a_wall_drawn_thick_or_a_little_off_is_not_doubled():
    truth = room()
    walls = truth.occupied_points()
    thick = np.vstack([walls + (0.0, dy) for dy in (-0.15, -0.1, -0.05, 0.0)])
    share, _ = doubled_walls(thick, truth, truth.data == OCCUPIED, 0.1)
    assert share == 0.0


def test_alignment_and_doubled_walls_name_bad_arguments():
    truth = room()
    with pytest.raises(InputError, match="tolerance"):
        align_map(truth.occupied_points(), truth, 0.0)
    with pytest.raises(InputError, match="min_gap"):
        doubled_walls(truth.occupied_points(), truth, None, 0.1, min_gap=2.0, max_gap=1.0)
    with pytest.raises(InputError, match="observed mask"):
        doubled_walls(truth.occupied_points(), truth, np.zeros((3, 3), bool), 0.1)


def test_the_alignment_search_convolves_as_scipy_signal_does():
    from scipy import signal

    from longslam.eval.map_align import _FullConvolution

    rng = np.random.default_rng(5)
    target = (rng.random((37, 52)) < 0.2).astype(np.float32)
    spectra = _FullConvolution(target)
    for shape in [(9, 14), (20, 3), (9, 14)]:  # the last one reuses the target's spectrum
        kernel = rng.random(shape).astype(np.float32)
        np.testing.assert_array_equal(spectra.convolve(kernel), signal.fftconvolve(target, kernel, mode="full"))


@pytest.mark.parametrize("radius", [0.5, 1.0, 2.0, 0.1 / 0.05, 3.7])
def test_near_cells_are_the_distance_transform_thresholded(radius):
    from scipy import ndimage

    from longslam.eval.doubled_walls import _near

    mask = np.random.default_rng(2).random((60, 80)) < 0.01
    expected = ndimage.distance_transform_edt(~mask) <= radius + 1e-9
    np.testing.assert_array_equal(_near(mask, radius), expected)
    assert not _near(np.zeros((5, 5), bool), radius).any()
