"""The range a frame's depth can be trusted to, measured from the frame: the noise in inverse
depth against each sensor model's formula, nothing limited under the ideal sensor (so ideal runs
are unchanged), and the front end counting the frames it limited."""

from __future__ import annotations

import math

import numpy as np
import pytest

from longslam.core.frame import Frame
from longslam.core.geometry import camera_poses_from_planar
from longslam.sim.sensors import FrameMotion, KinectV1, RealSenseD435, frame_rng
from longslam.slam.depth_trust import DepthTrust, inverse_depth_noise, scan_weight, trusted_depth, trusted_range
from longslam.slam.frontend import FrontEnd, FrontEndConfig

from helpers.flat_walls import K, TEXTURED_HALF, render, square_wall


@pytest.fixture(scope="module")
def wall_2m():
    rng = np.random.default_rng(7)
    texture = rng.integers(30, 225, (1024, 1024), dtype=np.uint8)[:, :, None].repeat(3, axis=2)
    return render([square_wall(2.0, TEXTURED_HALF)], texture)


def _sensed(model, rgb, depth):
    return model.sense(rgb, depth, K, FrameMotion.still(), frame_rng(model.name, 0, 0))[1]


def test_the_inverse_depth_noise_is_each_models_sigma_over_z_squared(wall_2m):
    rgb, depth = wall_2m
    kinect, realsense = KinectV1(), RealSenseD435()
    sigma_w, count = inverse_depth_noise(_sensed(kinect, rgb, depth))
    assert count > 10_000
    assert sigma_w == pytest.approx(kinect.axial_sigma(2.0) / 4.0, rel=0.15)
    assert inverse_depth_noise(_sensed(realsense, rgb, depth))[0] == pytest.approx(realsense.sigma(2.0) / 4.0, rel=0.15)
    # The D435's 1 cm / m^2 keeps 3 cm of noise to sqrt(3) m; the Kinect's to about 4.1 m.
    assert trusted_range(_sensed(realsense, rgb, depth)) == pytest.approx(math.sqrt(3.0), rel=0.1)
    assert 3.8 < trusted_range(_sensed(kinect, rgb, depth)) < 4.5


def test_ideal_depth_is_used_as_it_is(wall_2m):
    _, depth = wall_2m
    assert trusted_range(depth) is None
    stored = np.rint(depth * 5000.0) / 5000.0  # as a 16-bit PNG holds it
    assert trusted_range(stored.astype(np.float32)) is None
    assert trusted_depth(depth, None) is depth
    assert trusted_range(np.zeros((240, 320), np.float32)) is None  # nothing to measure


def test_trusted_depth_drops_the_far_returns_only():
    depth = np.array([[0.0, 1.0, 2.0, 3.0]], np.float32)
    assert trusted_depth(depth, 2.5).tolist() == [[0.0, 1.0, 2.0, 0.0]]
    assert trusted_range(np.random.default_rng(0).uniform(1, 4, (240, 320)).astype(np.float32),
                         DepthTrust(use=False)) is None


def test_the_front_end_limits_noisy_frames_and_not_clean_ones(wall_2m):
    rgb, depth = wall_2m
    noisy = _sensed(RealSenseD435(), rgb, depth)
    poses = camera_poses_from_planar(np.column_stack([0.05 * np.arange(6), np.zeros(6), np.zeros(6)]), 1.25)
    kinect = _sensed(KinectV1(), rgb, depth)
    counts = {}
    for name, d in (("clean", depth), ("kinect", kinect), ("d435", noisy)):
        front = FrontEnd(K)
        for i in range(6):
            front.step(Frame(i, 0.1 * i, rgb, d, poses[i], K))
        stats = front.stats
        counts[name] = (stats["depth_limited"], stats["depth_too_noisy"], stats["column_scans"], stats["scan_points"] > 0)
        if name == "d435":
            assert stats["trusted_range_mean_m"] == pytest.approx(math.sqrt(3.0), rel=0.1)
    # Clean depth is used as it is. The Kinect's is limited to about 4 m for its corners and its
    # scan is one averaged point per column; the D435's 1.7 m is too short to track on (min_range
    # 2.5 m), so its frames give the front end no scan at all.
    assert counts == {"clean": (0, 0, 0, True), "kinect": (6, 0, 6, True), "d435": (6, 6, 0, False)}


def test_scan_weight_is_one_for_exact_depth_and_falls_with_the_noise():
    trust = DepthTrust()
    assert scan_weight(None, trust) == 1.0  # exact depth: the registration exactly as before
    assert scan_weight(trust.scan_noise_half, trust) == pytest.approx(0.5)
    kinect = scan_weight(1.7e-3, trust)  # a Kinect v1's inverse-depth noise
    assert kinect == pytest.approx(1.0 / (1.0 + (1.7e-3 / 5e-5) ** 2))
    assert scan_weight(1e-2, trust) < kinect < scan_weight(1e-3, trust) < 1.0
    assert scan_weight(1.7e-3, DepthTrust(scan_noise_half=0.0)) == 1.0
    assert scan_weight(1.7e-3, DepthTrust(use=False)) == 1.0


def test_a_weighted_scan_informs_the_registration_less():
    from longslam.slam.frontend.local_map import LocalMap
    from longslam.slam.frontend.registration import register

    wall = np.column_stack([np.full(60, 2.0), np.linspace(-1.5, 1.5, 60)])
    floor = np.column_stack([np.linspace(0.5, 2.0, 30), np.full(30, -1.5)])
    local = LocalMap()
    local.insert(np.zeros(3), np.vstack([wall, floor]))
    scan = np.vstack([wall, floor])
    full = register(scan, np.array([0.02, 0.01, 0.0]), local)
    light = register(scan, np.array([0.02, 0.01, 0.0]), local, weight=0.01)
    assert full.ok and light.ok
    np.testing.assert_allclose(light.hessian, 0.01 * full.hessian, rtol=1e-6)


def test_a_method_gets_the_front_ends_limit_for_the_frame_it_stepped_without_measuring_again(wall_2m, monkeypatch):
    import longslam.slam.depth_trust as depth_trust
    import longslam.slam.frontend.motion as motion

    rgb, depth = wall_2m
    kinect = _sensed(KinectV1(), rgb, depth)
    poses = camera_poses_from_planar(np.zeros((2, 3)), 1.25)
    step = FrontEnd(K).step(Frame(0, 0.0, rgb, kinect, poses[0], K))
    limit = trusted_range(kinect)
    assert limit is not None  # a Kinect frame is limited, not used as it is
    expected = trusted_depth(kinect, limit)
    measured = []
    real = depth_trust.inverse_depth_noise
    monkeypatch.setattr(depth_trust, "inverse_depth_noise", lambda *a, **k: measured.append(1) or real(*a, **k))
    stepped = step.depths(kinect).trusted
    assert measured == []  # the stepped frame's range, as the front end measured it
    np.testing.assert_array_equal(stepped, expected)
    # On wheels alone the step looks at no depth: the range is measured when the method asks.
    wheels = FrontEnd(K, FrontEndConfig(mode="wheel")).step(Frame(0, 0.0, rgb, kinect, poses[0], K))
    assert not wheels.depth_measured
    np.testing.assert_array_equal(wheels.depths(kinect).trusted, stepped)
    assert len(measured) == 1
    assert isinstance(wheels, motion.FrameStep)
