"""Trajectory metrics: the paper's on hand-made cases with known answers, APE / RPE / association
against evo (GPLv3, used here only as an independent check; longslam never imports it)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from longslam.core.errors import InputError, TrajectoryError, UnknownNameError
from longslam.eval import metrics as lm
from longslam.eval.evaluation import evaluate
from longslam.eval.align import align_trajectory, umeyama
from longslam.eval.sync import associate, associate_by_index
from longslam.core.timestamps import one_to_one_nearest
from longslam.core.geometry import planar_poses, tum_from_poses
from longslam.core.trajectory import Trajectory

evo_metrics = pytest.importorskip("evo.core.metrics")
from evo.core import filters as evo_filters  # noqa: E402
from evo.core import geometry as evo_geometry  # noqa: E402
from evo.core import sync as evo_sync  # noqa: E402
from evo.core import trajectory as evo_trajectory  # noqa: E402
from evo.core.units import Unit  # noqa: E402

TOL = 1e-9


# ----------------------------------------------------------------------------- helpers


def smooth_trajectory(
    rng: np.random.Generator, n: int = 400, dt: float = 0.1, t0: float = 1000.0
) -> Trajectory:
    """A random smooth 3D trajectory: sums of sinusoids for position and Euler angles."""
    t = np.arange(n) * dt
    freq = rng.uniform(0.02, 0.3, size=(3, 3))
    phase = rng.uniform(0, 2 * np.pi, size=(3, 3))
    amp = rng.uniform(1.0, 6.0, size=(3, 3)) * np.array([[1.0], [1.0], [0.2]])
    positions = np.sum(amp[None] * np.sin(freq[None] * t[:, None, None] + phase[None]), axis=2)
    positions += rng.normal(size=3) * t[:, None] * 0.5  # a drift so the path keeps going
    angle_freq = rng.uniform(0.05, 0.4, size=3)
    angle_amp = np.array([np.pi, 0.2, 0.1])
    angles = angle_amp * np.sin(angle_freq * t[:, None] + rng.uniform(0, 2 * np.pi, size=3))
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, :3] = Rotation.from_euler("zyx", angles).as_matrix()
    poses[:, :3, 3] = positions
    return Trajectory(t0 + t, poses, source="reference")


def noisy_estimate(rng: np.random.Generator, reference: Trajectory, scale: float = 1.0) -> Trajectory:
    """The reference with drifting position and rotation errors, then moved and scaled by a Sim(3)."""
    n = len(reference)
    drift = np.cumsum(rng.normal(scale=0.02, size=(n, 3)), axis=0)
    rot_drift = Rotation.from_rotvec(np.cumsum(rng.normal(scale=0.004, size=(n, 3)), axis=0))
    offset_rot = Rotation.from_rotvec(rng.normal(scale=0.5, size=3)).as_matrix()
    offset_t = rng.normal(scale=3.0, size=3)
    poses = reference.poses.copy()
    poses[:, :3, :3] = offset_rot @ (reference.poses[:, :3, :3] @ rot_drift.as_matrix())
    poses[:, :3, 3] = scale * (reference.positions + drift) @ offset_rot.T + offset_t
    return Trajectory(reference.timestamps, poses, source="estimate")


def to_evo(trajectory: Trajectory) -> evo_trajectory.PoseTrajectory3D:
    quat_xyzw = tum_from_poses(trajectory.poses)[:, 3:]
    return evo_trajectory.PoseTrajectory3D(
        positions_xyz=trajectory.positions,
        orientations_quat_wxyz=quat_xyzw[:, [3, 0, 1, 2]],
        timestamps=trajectory.timestamps,
    )


def straight_line(n: int, step: float, yaw: float = 0.0) -> Trajectory:
    """Poses along world x, `step` apart, all facing `yaw`."""
    xyyaw = np.column_stack([np.arange(n) * step, np.zeros(n), np.full(n, yaw)])
    return Trajectory(np.arange(n) * 0.1, planar_poses(xyyaw))


def from_positions(positions: np.ndarray, yaws: np.ndarray | float = 0.0) -> Trajectory:
    positions = np.asarray(positions, dtype=np.float64)
    yaw = np.broadcast_to(yaws, (len(positions),))
    poses = planar_poses(np.column_stack([positions[:, 0], positions[:, 1], yaw]))
    poses[:, 2, 3] = positions[:, 2]
    return Trajectory(np.arange(len(positions)) * 0.1, poses)


@pytest.fixture(scope="module")
def pair() -> tuple[Trajectory, Trajectory]:
    rng = np.random.default_rng(20240611)
    reference = smooth_trajectory(rng)
    return reference, noisy_estimate(rng, reference, scale=1.3)


# ----------------------------------------------------------------------------- APE against evo


@pytest.mark.parametrize("mode", ["none", "se3", "sim3"])
def test_ape_translation_matches_evo(pair, mode):
    reference, estimate = pair
    ours = lm.ape(reference, estimate, align=mode)

    evo_ref, evo_est = to_evo(reference), to_evo(estimate)
    if mode != "none":
        evo_est.align(evo_ref, correct_scale=mode == "sim3")
    metric = evo_metrics.APE(evo_metrics.PoseRelation.translation_part)
    metric.process_data((evo_ref, evo_est))
    expected = metric.get_all_statistics()

    for name in ("rmse", "mean", "median", "std", "min", "max"):
        assert ours[name] == pytest.approx(expected[name], abs=TOL, rel=TOL), name
    # The alignment must matter on this data, or the test could not tell the modes apart.
    assert lm.ape(reference, estimate, "none")["rmse"] > 2 * lm.ape(reference, estimate, "se3")["rmse"]


@pytest.mark.parametrize("mode", ["none", "se3"])
def test_ape_rotation_matches_evo(pair, mode):
    reference, estimate = pair
    ours = lm.ape(reference, estimate, align=mode, part="rotation")
    evo_ref, evo_est = to_evo(reference), to_evo(estimate)
    if mode != "none":
        evo_est.align(evo_ref)
    metric = evo_metrics.APE(evo_metrics.PoseRelation.rotation_angle_deg)
    metric.process_data((evo_ref, evo_est))
    expected = metric.get_all_statistics()
    for name in ("rmse", "mean", "median", "max"):
        assert ours[name] == pytest.approx(expected[name], abs=TOL, rel=TOL), name


def test_umeyama_recovers_a_known_similarity_and_matches_evo():
    rng = np.random.default_rng(7)
    source = rng.normal(size=(50, 3)) * [5.0, 3.0, 1.0]
    rotation = Rotation.from_rotvec([0.3, -1.1, 2.0]).as_matrix()
    target = 0.7 * source @ rotation.T + [1.0, -2.0, 3.0]
    r, t, s = umeyama(source, target, with_scale=True)
    np.testing.assert_allclose(r, rotation, atol=1e-12)
    np.testing.assert_allclose(t, [1.0, -2.0, 3.0], atol=1e-12)
    assert s == pytest.approx(0.7, abs=1e-12)

    noisy = target + rng.normal(scale=0.1, size=target.shape)
    mirrored = noisy * [-1.0, 1.0, 1.0]  # best orthogonal fit is a reflection: R must stay proper
    for points in (noisy, mirrored):
        for with_scale in (False, True):
            ours = umeyama(source, points, with_scale)
            theirs = evo_geometry.umeyama_alignment(source.T, points.T, with_scale)
            for a, b in zip(ours, theirs):
                np.testing.assert_allclose(a, b, atol=1e-10)
            assert np.linalg.det(ours[0]) == pytest.approx(1.0)


def test_rotation_angle_is_accurate_near_0_and_180_degrees():
    rng = np.random.default_rng(2)
    angles = np.radians([1e-7, 1e-4, 0.5, 90.0, 179.5, 180.0 - 1e-6])
    axes = rng.normal(size=(len(angles), 3))
    rotvecs = axes / np.linalg.norm(axes, axis=1, keepdims=True) * angles[:, None]
    got = lm.rotation_angle_deg(Rotation.from_rotvec(rotvecs).as_matrix())
    np.testing.assert_allclose(got, np.degrees(angles), rtol=1e-7, atol=1e-12)


def test_aligned_trajectory_rotates_orientations_too(pair):
    reference, estimate = pair
    aligned = align_trajectory(estimate, reference, "se3")
    evo_est = to_evo(estimate)
    evo_est.align(to_evo(reference))
    np.testing.assert_allclose(aligned.poses, np.array(evo_est.poses_se3), atol=1e-9)


# ----------------------------------------------------------------------------- RPE against evo


@pytest.mark.parametrize(
    "delta, unit, all_pairs, from_reference",
    [
        (1.0, "m", False, False),
        (1.0, "m", True, False),
        (2.5, "m", False, True),
        (1.0, "m", True, True),
        (1, "frames", False, False),
        (7, "frames", False, False),
        (7, "frames", True, False),
    ],
)
def test_rpe_matches_evo(pair, delta, unit, all_pairs, from_reference):
    reference, estimate = pair
    ours = lm.rpe(reference, estimate, delta, unit, all_pairs=all_pairs, pairs_from_reference=from_reference)
    evo_unit = Unit.meters if unit == "m" else Unit.frames
    for relation, key in (
        (evo_metrics.PoseRelation.translation_part, "translation"),
        (evo_metrics.PoseRelation.rotation_angle_deg, "rotation"),
    ):
        metric = evo_metrics.RPE(
            relation, delta, evo_unit, all_pairs=all_pairs, pairs_from_reference=from_reference
        )
        metric.process_data((to_evo(reference), to_evo(estimate)))
        expected = metric.get_all_statistics()
        assert ours["pairs"] == len(metric.error)
        for name in ("rmse", "mean", "median", "std", "min", "max"):
            assert ours[key][name] == pytest.approx(expected[name], abs=TOL, rel=TOL), (key, name)


def test_path_pairs_match_evo_on_exact_steps_and_standing_still():
    # Steps of exactly 0.1 m: ten of them sum to 0.9999999999999999 in evo's loop, so the choice
    # of pairs depends on summing exactly as evo does. Standing still makes runs of equal distance.
    rng = np.random.default_rng(3)
    x = np.concatenate([np.arange(40) * 0.1, np.full(6, 3.9), 3.9 + np.arange(1, 40) * 0.1])
    positions = np.column_stack([x, np.zeros_like(x), np.zeros_like(x)])
    wiggly = positions + np.column_stack([np.zeros_like(x), rng.normal(scale=0.05, size=(len(x), 2))])
    for points in (positions, wiggly):
        poses = [np.block([[np.eye(3), p[:, None]], [np.zeros((1, 3)), 1.0]]) for p in points]
        # 1.02 m puts the target just past the standing-still run, whose first pose evo picks.
        for delta, all_pairs in ((1.0, False), (0.5, False), (1.0, True), (0.3, True), (1.02, True)):
            tol = 0.1 * delta
            first, second = lm.pairs_by_path(points, delta, tol, all_pairs)
            expected = evo_filters.filter_pairs_by_path(poses, delta, tol, all_pairs)
            assert list(zip(first.tolist(), second.tolist())) == expected, (delta, all_pairs)
    # Delta exactly evo's sum of the first ten diagonal steps, and one bit either side: the pairs
    # hang on the last bit of the summed path, whatever numpy's norm kernels do.
    points = np.arange(60)[:, None] * np.array([0.07, 0.11, 0.13])
    for delta in _bits_around(_evo_path(points, 10)):
        poses = [np.block([[np.eye(3), p[:, None]], [np.zeros((1, 3)), 1.0]]) for p in points]
        first, second = lm.pairs_by_path(points, delta)
        expected = evo_filters.filter_pairs_by_path(poses, delta)
        assert list(zip(first.tolist(), second.tolist())) == expected, delta
    assert expected[0] == (0, 11)  # one bit above evo's sum of ten steps takes an eleventh

    for n, delta, all_pairs in ((20, 3, False), (20, 3, True), (5, 7, True), (21, 5, False)):
        first, second = lm.pairs_by_index(n, delta, all_pairs)
        expected = evo_filters.filter_pairs_by_index(list(range(n)), delta, all_pairs)
        assert list(zip(first.tolist(), second.tolist())) == expected


def _evo_path(points: np.ndarray, k: int) -> float:
    """The path over the first k steps summed as evo does: one vector's norm at a time."""
    path = 0.0
    for a, b in zip(points[:k], points[1 : k + 1]):
        path += float(np.linalg.norm(b - a))
    return path


def _bits_around(value: float) -> list[float]:
    return [np.nextafter(value, -np.inf), value, np.nextafter(value, np.inf)]


def test_path_pairs_match_evo_where_a_rowwise_norm_rounds_apart():
    # Diagonal steps whose lengths evo (one vector at a time) and a row-wise norm round apart in
    # the last bit, with delta exactly evo's sum of the first ten: the pairs then hang on that bit.
    # Some numpy versions (2.4 on x86-64, for one) compute both norms alike; there the case
    # cannot be built, and the exact-sum checks above still hold.
    for step in np.random.default_rng(5).uniform(0.01, 0.2, size=(1000, 3)):
        points = np.arange(60)[:, None] * step
        delta = _evo_path(points, 10)
        if np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))[9] < delta:
            break
    else:
        pytest.skip(f"numpy {np.__version__}: row-wise and one-vector norms agree on every step tried")
    poses = [np.block([[np.eye(3), p[:, None]], [np.zeros((1, 3)), 1.0]]) for p in points]
    first, second = lm.pairs_by_path(points, delta)
    expected = evo_filters.filter_pairs_by_path(poses, delta)
    assert list(zip(first.tolist(), second.tolist())) == expected
    assert expected[0] == (0, 10)


def test_rpe_rejects_bad_arguments(pair):
    reference, estimate = pair
    with pytest.raises(UnknownNameError, match="frames"):
        lm.rpe(reference, estimate, 1.0, unit="seconds")
    with pytest.raises(InputError, match="whole number"):
        lm.rpe(reference, estimate, 1.5, unit="frames")
    with pytest.raises(TrajectoryError, match="smaller delta"):
        lm.rpe(reference, estimate, 1e6, unit="m")


# ----------------------------------------------------------------------------- association


def _jittered_pair(rng):
    ref_stamps = 100.0 + np.arange(300) * 0.1 + rng.uniform(-0.003, 0.003, 300)
    est_stamps = 105.0 + np.arange(400) * 0.1 + rng.uniform(-0.004, 0.004, 400)
    est_stamps = est_stamps[np.sort(rng.choice(400, 320, replace=False))]  # dropped frames
    return ref_stamps, est_stamps


def _with_stamps(trajectory: Trajectory, stamps: np.ndarray) -> Trajectory:
    return Trajectory(stamps, trajectory.poses[: len(stamps)])


@pytest.mark.parametrize("offset, swap", [(0.0, False), (0.0, True), (0.05, False), (-0.03, True)])
def test_associate_matches_evo(offset, swap):
    rng = np.random.default_rng(11)
    ref_stamps, est_stamps = _jittered_pair(rng)
    if swap:  # make the reference the shorter one
        ref_stamps, est_stamps = est_stamps[:250], ref_stamps
    base = smooth_trajectory(rng, n=400)
    reference = _with_stamps(base, ref_stamps)
    estimate = _with_stamps(noisy_estimate(rng, base), est_stamps + offset)
    ours_ref, ours_est = associate(reference, estimate, max_diff=0.01, offset=-offset)
    evo_ref, evo_est = evo_sync.associate_trajectories(
        to_evo(reference), to_evo(estimate), max_diff=0.01, offset_2=-offset
    )
    np.testing.assert_array_equal(ours_ref.timestamps, evo_ref.timestamps)
    np.testing.assert_array_equal(ours_est.timestamps, evo_est.timestamps)
    np.testing.assert_allclose(ours_est.positions, evo_est.positions_xyz)
    # A real overlap, not everything and not nothing.
    assert 0.5 * min(len(reference), len(estimate)) <= len(ours_ref) < min(len(reference), len(estimate))


def test_associate_is_one_to_one():
    # 0.0 and 0.004 both have 0.001 as nearest stamp; evo would pair both with it.
    short, long = np.array([0.0, 0.004, 0.1, 0.2]), np.array([0.001, 0.1, 0.2, 0.3, 0.4])
    short_idx, long_idx = one_to_one_nearest(short, long, 0.01)
    assert short_idx.tolist() == [0, 2, 3]
    assert long_idx.tolist() == [0, 1, 2]
    # Keeping the closer one: here 0.004 is closer to 0.006.
    short_idx, long_idx = one_to_one_nearest(np.array([0.0, 0.004]), np.array([0.006, 0.5, 0.9]), 0.01)
    assert short_idx.tolist() == [1] and long_idx.tolist() == [0]


def test_matching_breaks_ties_like_evo():
    # Stamps exact in binary: 0.25 lies exactly between 0.0 and 0.5, 1.125 between 1.0 and 1.25.
    short, long = np.array([0.25, 1.125, 2.0]), np.array([0.0, 0.5, 1.0, 1.25, 1.875, 2.125])
    ours = one_to_one_nearest(short, long, 0.25)
    theirs = evo_sync.matching_time_indices(short, long, 0.25)
    assert (ours[0].tolist(), ours[1].tolist()) == theirs
    assert theirs == ([0, 1, 2], [0, 2, 4])


def test_associate_too_few_matches_says_how_many():
    reference = straight_line(20, 0.1)
    shifted = Trajectory(reference.timestamps + 0.05, reference.poses)
    with pytest.raises(TrajectoryError, match=r"only 0 of 20 .*max_diff 0\.01"):
        associate(reference, shifted)
    # 8 of 20 overlap: fewer than half.
    partial = Trajectory(reference.timestamps + 1.2, reference.poses)
    with pytest.raises(TrajectoryError, match=r"only 8 of 20"):
        associate(reference, partial)
    # The same pair matches with the right offset.
    ref, est = associate(reference, partial, offset=-1.2)
    assert len(ref) == len(est) == 20


def test_associate_by_index_needs_equal_lengths():
    a, b = straight_line(10, 0.1), straight_line(9, 0.1)
    assert associate_by_index(a, straight_line(10, 0.2))[0] is a
    with pytest.raises(TrajectoryError, match="10 poses.* 9"):
        associate_by_index(a, b)


# ----------------------------------------------------------------------------- the paper's metrics


def test_constant_scale_error_on_a_straight_line():
    reference = straight_line(101, 0.1)
    estimate = from_positions(reference.positions * 1.05)
    rel = lm.relative_errors(reference, estimate)
    assert rel.e_trans == pytest.approx(0.05, abs=1e-12)
    assert rel.e_rot == pytest.approx(0.0, abs=1e-9)
    assert rel.used_steps == 100 and rel.skipped_steps == 0
    assert lm.ate(reference, estimate) == pytest.approx(0.05 * 5.0, abs=1e-12)  # 5% of mean x = 5 m


def test_constant_offset_changes_ate_only(pair):
    reference, _ = pair
    poses = reference.poses.copy()
    poses[:, :3, 3] += [0.3, -0.4, 0.0]
    estimate = Trajectory(reference.timestamps, poses)
    assert lm.ate(reference, estimate) == pytest.approx(0.5, abs=1e-12)
    rel = lm.relative_errors(reference, estimate)
    assert rel.e_trans == pytest.approx(0.0, abs=1e-9)
    assert rel.e_rot == pytest.approx(0.0, abs=1e-6)


def test_yawed_steps_give_known_rotation_error():
    # Ground truth: 0.2 m steps straight ahead. Estimate: each step turned 10 deg to the left
    # in the frame of the previous pose (with the heading left unchanged).
    n, step, yaw = 30, 0.2, np.radians(10.0)
    reference = straight_line(n, step)
    positions = np.zeros((n, 3))
    positions[1:, :2] = np.cumsum(np.tile([step * np.cos(yaw), step * np.sin(yaw)], (n - 1, 1)), axis=0)
    estimate = from_positions(positions)
    rel = lm.relative_errors(reference, estimate)
    assert rel.e_rot == pytest.approx(10.0 / step, rel=1e-9)  # 50 deg/m
    assert rel.e_trans == pytest.approx(2 * np.sin(yaw / 2), rel=1e-9)
    np.testing.assert_allclose(rel.step_e_rot, 50.0, rtol=1e-9)


def test_relative_errors_use_each_pose_frame():
    # The whole estimate turned 30 deg about the origin: every step is the same in its own frame,
    # so E_trans and E_rot are 0 while ATE is not.
    reference = straight_line(20, 0.15)
    turn = planar_poses(np.array([[0.0, 0.0, np.radians(30.0)]]))[0]
    estimate = Trajectory(reference.timestamps, turn @ reference.poses)
    rel = lm.relative_errors(reference, estimate)
    assert rel.e_trans == pytest.approx(0.0, abs=1e-12)
    assert rel.e_rot == pytest.approx(0.0, abs=1e-6)
    assert lm.ate(reference, estimate) > 0.3
    # Same positions but headings off by 10 deg: each step seen 10 deg off in the estimate's frame.
    estimate = from_positions(reference.positions, np.radians(10.0))
    assert lm.relative_errors(reference, estimate).e_rot == pytest.approx(10.0 / 0.15, rel=1e-9)


def test_turning_in_place_is_skipped_and_counted():
    # 5 steps of 0.1 m, 4 steps turning on the spot (creeping 2 mm each, under the 1 cm floor),
    # 5 more steps. The estimate overshoots by 10% when moving and creeps 1.25 mm per turning
    # step: counted, each turning step would add 0.75 mm / 2 mm = 0.375 to E_trans.
    xyyaw = [(0.1 * i, 0.0, 0.0) for i in range(6)]
    xyyaw += [(0.5 + 0.002 * k, 0.0, np.radians(22.5) * k) for k in range(1, 5)]
    xyyaw += [(0.508, 0.1 * i, np.pi / 2) for i in range(1, 6)]
    reference = Trajectory(np.arange(len(xyyaw)) * 0.1, planar_poses(np.array(xyyaw)))
    est = np.array(xyyaw)
    est[:6, 0] *= 1.1
    est[6:10, 0] = 0.55 + 0.00125 * np.arange(1, 5)
    est[10:, 0] = est[9, 0]
    est[10:, 1] = 0.11 * np.arange(1, 6)
    estimate = Trajectory(reference.timestamps, planar_poses(est))
    rel = lm.relative_errors(reference, estimate)
    assert rel.skipped_steps == 4 and rel.used_steps == 10
    assert rel.steps.tolist() == [1, 2, 3, 4, 5, 10, 11, 12, 13, 14]
    assert rel.e_trans == pytest.approx(0.1, rel=1e-9)
    assert rel.e_rot == pytest.approx(0.0, abs=1e-6)
    # A lower floor lets the turning steps in, with their large error per metre.
    low = lm.relative_errors(reference, estimate, min_step=1e-3)
    assert low.skipped_steps == 0 and low.used_steps == 14
    assert low.e_trans == pytest.approx((10 * 0.1 + 4 * 0.375) / 14, rel=1e-9)
    with pytest.raises(InputError, match="min_step"):
        lm.relative_errors(reference, estimate, min_step=0.0)
    expected_distance = [0.1, 0.2, 0.3, 0.4, 0.5, 0.608, 0.708, 0.808, 0.908, 1.008]
    np.testing.assert_allclose(rel.distance, expected_distance, atol=1e-12)
    assert np.all(np.isfinite(rel.step_e_rot)) and np.all(np.isfinite(rel.step_e_trans))


def test_stalled_estimate_gives_finite_errors():
    reference = straight_line(10, 0.1)
    estimate = Trajectory(reference.timestamps, np.tile(np.eye(4), (10, 1, 1)))
    rel = lm.relative_errors(reference, estimate)
    assert rel.e_trans == pytest.approx(1.0)
    assert rel.e_rot == pytest.approx(90.0 / 0.1)
    assert rel.zero_estimate_steps == 9


def test_no_moving_step_is_an_error():
    turning = np.column_stack([np.zeros(5), np.zeros(5), np.arange(5.0)])
    still = Trajectory(np.arange(5) * 0.1, planar_poses(turning))
    with pytest.raises(TrajectoryError, match="min_step"):
        lm.relative_errors(still, still)


# ----------------------------------------------------------------------------- evaluate and errors


def test_evaluate_is_flat_finite_json_and_consistent(pair):
    reference, estimate = pair
    result = evaluate(reference, estimate, align="se3")
    required = {
        "ate", "e_trans", "e_rot", "skipped_steps", "ape_rmse", "ape_mean", "ape_median", "ape_max",
        "rpe_trans", "rpe_rot", "matched_poses", "path_length", "align",
    }
    assert required <= result.keys()
    json.dumps(result, allow_nan=False)
    assert all(np.isfinite(v) for v in result.values() if not isinstance(v, str))
    assert result["matched_poses"] == len(reference)
    assert result["path_length"] == pytest.approx(reference.path_length())
    assert result["ate"] == pytest.approx(lm.ate(reference, estimate))
    assert result["ape_rmse"] == pytest.approx(lm.ape(reference, estimate, "se3")["rmse"])
    # rpe_trans is evo_rpe -d 1 -u m --pairs_from_reference on the SE(3)-aligned estimate.
    metric = evo_metrics.RPE(
        evo_metrics.PoseRelation.translation_part, 1.0, Unit.meters, pairs_from_reference=True
    )
    evo_est = to_evo(estimate)
    evo_est.align(to_evo(reference))
    metric.process_data((to_evo(reference), evo_est))
    expected = metric.get_statistic(evo_metrics.StatisticsType.rmse)
    assert result["rpe_trans"] == pytest.approx(expected, abs=TOL)


def test_errors_by_distance():
    reference = straight_line(11, 0.5)
    estimate = from_positions(reference.positions + [0.0, 0.2, 0.0])
    distance, error = lm.errors_by_distance(reference, estimate)
    np.testing.assert_allclose(distance, np.arange(11) * 0.5, atol=1e-12)
    np.testing.assert_allclose(error, 0.2, atol=1e-12)


def test_unequal_lengths_are_refused():
    a, b = straight_line(10, 0.1), straight_line(12, 0.1)
    for call in (lm.ate, lm.relative_errors, lm.ape, lm.rpe, evaluate, lm.errors_by_distance):
        with pytest.raises(TrajectoryError, match="10 poses but .* 12"):
            call(a, b)


def test_alignment_errors_are_clear(pair):
    reference, estimate = pair
    with pytest.raises(UnknownNameError, match="none, origin, scale, se3, sim3"):
        lm.ape(reference, estimate, align="sim2")
    with pytest.raises(UnknownNameError, match="rotation, translation"):
        lm.ape(reference, estimate, part="full")
    line = straight_line(10, 0.1)
    with pytest.raises(TrajectoryError, match="straight line"):
        align_trajectory(from_positions(line.positions * 2), line, "sim3")
    with pytest.raises(TrajectoryError, match="at least 3"):
        align_trajectory(reference.subset(np.arange(2)), reference.subset(np.arange(2)), "se3")
