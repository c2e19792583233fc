"""Noisy depth as one averaged scan point per image column, weighed by its own noise."""

import numpy as np
import pytest

from longslam.core.frame import Intrinsics
from longslam.core.geometry import base_to_camera
from longslam.slam.frontend.local_map import LocalMap
from longslam.slam.frontend.registration import register
from longslam.slam.frontend.scan import ScanExtractor

INTR = Intrinsics.from_fov(320, 240, 90.0)
D435_SIGMA_W = 1e-2  # 1/m: 9 cm of axial noise at 3 m


def _noisy_wall(z: float, sigma_w: float, seed: int = 0) -> np.ndarray:
    """A wall facing the camera at depth z, each pixel with independent noise sigma_w z^2."""
    rng = np.random.default_rng(seed)
    return (z + sigma_w * z * z * rng.standard_normal((240, 320))).astype(np.float32)


def test_a_noisy_wall_gives_one_point_per_column_as_sure_as_its_returns_make_it():
    ex = ScanExtractor(INTR, base_to_camera(1.25))
    points, noise = ex.columns(_noisy_wall(3.0, D435_SIGMA_W), D435_SIGMA_W, 4, 0.05, 1.0)
    assert 100 <= len(points) <= 160  # a column every 2 pixels
    assert len(np.unique(np.round(points[:, 1], 4))) == len(points)
    # A pixel's 9 cm of noise, averaged over the band's rows (1.3 m of wall at 3 m: ~30 sampled
    # rows), is a few cm; each point's own figure says how far it is off.
    error = points[:, 0] - 3.0
    assert 0.01 < noise.mean() < 0.03
    assert np.std(error / noise) == pytest.approx(1.0, abs=0.2)
    assert abs(error.mean()) < 4 * noise.mean() / np.sqrt(len(points))
    # Cut to 5 cm cells instead, the same returns spread across several cells along each ray.
    cells = ex(_noisy_wall(3.0, D435_SIGMA_W))
    assert np.std(cells[:, 0] - 3.0) > 2 * np.std(error)


def test_columns_too_noisy_or_too_thin_give_no_point():
    ex = ScanExtractor(INTR, base_to_camera(1.25))
    far, _ = ex.columns(_noisy_wall(7.0, D435_SIGMA_W), D435_SIGMA_W, 4, 0.05, 1.0)
    assert len(far) == 0  # 49 cm a pixel: no average of a band's rows gets under 5 cm
    # Correlated noise counts fewer independent returns: a point is less sure.
    _, independent = ex.columns(_noisy_wall(3.0, D435_SIGMA_W), D435_SIGMA_W, 4, 0.05, 1.0)
    _, correlated = ex.columns(_noisy_wall(3.0, D435_SIGMA_W), D435_SIGMA_W, 4, 0.05, 4.0)
    assert correlated.mean() == pytest.approx(2.0 * independent.mean(), rel=0.1)
    sparse = np.zeros((240, 320), np.float32)
    sparse[120:123] = 3.0  # three rows of returns, sampled every second row: two a column
    assert len(ex.columns(sparse, 1e-3, 4, 0.05, 1.0)[0]) == 0
    assert len(ex.columns(sparse, 1e-3, 2, 0.05, 1.0)[0]) > 100


def test_a_column_takes_the_range_most_of_its_returns_agree_on():
    ex = ScanExtractor(INTR, base_to_camera(1.25))
    depth = np.full((240, 320), 3.0, np.float32)
    depth[150:175] = 2.0  # a table edge across the lower part of the band, a minority of its rows
    points, _ = ex.columns(depth, 1e-3, 4, 0.05, 1.0)
    np.testing.assert_allclose(points[:, 0], 3.0, atol=1e-5)


def _wall_and_floor() -> tuple[LocalMap, np.ndarray]:
    wall = np.column_stack([np.full(60, 2.0), np.linspace(-1.5, 1.5, 60)])
    side = np.column_stack([np.linspace(0.5, 2.0, 30), np.full(30, -1.5)])
    scan = np.vstack([wall, side])
    local = LocalMap()
    local.insert(np.zeros(3), scan)
    return local, scan


def test_points_without_noise_register_as_an_unweighted_scan():
    local, scan = _wall_and_floor()
    guess = np.array([0.02, 0.01, 0.01])
    plain = register(scan, guess, local)
    exact = register(scan, guess, local, point_sigma=np.zeros(len(scan)))
    np.testing.assert_array_equal(plain.pose, exact.pose)
    np.testing.assert_array_equal(plain.hessian, exact.hessian)


def test_noisy_points_inform_the_registration_less_than_sure_ones():
    local, scan = _wall_and_floor()
    guess = np.array([0.02, 0.01, 0.0])
    sure = register(scan, guess, local, point_sigma=np.full(len(scan), 0.005))
    noisy_wall = np.r_[np.full(60, 0.06), np.full(30, 0.005)]
    unsure = register(scan, guess, local, point_sigma=noisy_wall)
    assert sure.ok and unsure.ok
    # The wall holds x: its noisy points hold it a fifth as much (0.03^2 / (0.03^2 + 0.06^2)).
    ratio = (0.03**2 + 0.005**2) / (0.03**2 + 0.06**2)
    assert unsure.hessian[0, 0] == pytest.approx(sure.hessian[0, 0] * ratio, rel=0.02)
    # The side wall holds y (the wall's end points, near the corner, lean on it a little too).
    assert unsure.hessian[1, 1] > 0.9 * sure.hessian[1, 1]
    np.testing.assert_allclose(unsure.pose[:2], [0.0, 0.0], atol=2e-3)
