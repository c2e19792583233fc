"""`evaluate` with evo's options, each checked against evo's own evo_ape / evo_rpe code (GPLv3, a
test-only dependency: longslam computes the figures itself and never imports evo)."""

from __future__ import annotations

import copy
import inspect
import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from longslam.cli.main import build_parser, main
from longslam.eval import metrics as lm
from longslam.eval.evaluation import evaluate
from longslam.eval.relations import APE_RELATIONS, RPE_RELATIONS
from longslam.core.geometry import tum_from_poses
from longslam.io.trajectory_files import write_tum
from longslam.core.trajectory import Trajectory

pytest.importorskip("evo.core.metrics")
from evo.core import metrics as evo_metrics  # noqa: E402
from evo.core import sync as evo_sync  # noqa: E402
from evo.core import trajectory as evo_trajectory  # noqa: E402
from evo.core.units import Unit  # noqa: E402
from evo.main_ape import ape as evo_ape  # noqa: E402
from evo.main_rpe import rpe as evo_rpe  # noqa: E402

DIGITS = 1e-6  # "to 6 digits": relative
EVO_RELATIONS = {
    "trans_part": evo_metrics.PoseRelation.translation_part,
    "rot_part": evo_metrics.PoseRelation.rotation_part,
    "full": evo_metrics.PoseRelation.full_transformation,
    "angle_deg": evo_metrics.PoseRelation.rotation_angle_deg,
    "angle_rad": evo_metrics.PoseRelation.rotation_angle_rad,
    "point_distance": evo_metrics.PoseRelation.point_distance,
    "point_distance_error_ratio": evo_metrics.PoseRelation.point_distance_error_ratio,
}
EVO_UNITS = {"f": Unit.frames, "m": Unit.meters, "d": Unit.degrees, "r": Unit.radians}
STATS = ("rmse", "mean", "median", "std", "min", "max")


def smooth_trajectory(rng: np.random.Generator, n: int = 200, dt: float = 0.1, t0: float = 1000.0) -> Trajectory:
    t = np.arange(n) * dt
    freq = rng.uniform(0.02, 0.3, size=(3, 3))
    phase = rng.uniform(0, 2 * np.pi, size=(3, 3))
    amp = rng.uniform(1.0, 6.0, size=(3, 3)) * np.array([[1.0], [1.0], [0.2]])
    positions = np.sum(amp[None] * np.sin(freq[None] * t[:, None, None] + phase[None]), axis=2)
    positions += rng.normal(size=3) * t[:, None] * 0.5
    angles = np.array([np.pi, 0.2, 0.1]) * np.sin(rng.uniform(0.05, 0.4, size=3) * t[:, None]
                                                  + rng.uniform(0, 2 * np.pi, size=3))
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, :3] = Rotation.from_euler("zyx", angles).as_matrix()
    poses[:, :3, 3] = positions
    return Trajectory(t0 + t, poses, source="reference")


def noisy_estimate(rng: np.random.Generator, reference: Trajectory, scale: float = 1.3) -> Trajectory:
    n = len(reference)
    drift = np.cumsum(rng.normal(scale=0.02, size=(n, 3)), axis=0)
    rot_drift = Rotation.from_rotvec(np.cumsum(rng.normal(scale=0.004, size=(n, 3)), axis=0))
    offset_rot = Rotation.from_rotvec(rng.normal(scale=0.5, size=3)).as_matrix()
    poses = reference.poses.copy()
    poses[:, :3, :3] = offset_rot @ (reference.poses[:, :3, :3] @ rot_drift.as_matrix())
    poses[:, :3, 3] = scale * (reference.positions + drift) @ offset_rot.T + rng.normal(scale=3.0, size=3)
    return Trajectory(reference.timestamps, poses, source="estimate")


def to_evo(trajectory: Trajectory) -> evo_trajectory.PoseTrajectory3D:
    quat_xyzw = tum_from_poses(trajectory.poses)[:, 3:]
    return evo_trajectory.PoseTrajectory3D(positions_xyz=trajectory.positions,
                                           orientations_quat_wxyz=quat_xyzw[:, [3, 0, 1, 2]],
                                           timestamps=trajectory.timestamps)


@pytest.fixture(scope="module")
def pair() -> tuple[Trajectory, Trajectory]:
    rng = np.random.default_rng(24)
    reference = smooth_trajectory(rng)
    return reference, noisy_estimate(rng, reference)


EVO_ALIGN = {  # longslam's mode -> evo_ape's switches
    "none": {}, "se3": {"align": True}, "sim3": {"align": True, "correct_scale": True},
    "scale": {"correct_scale": True}, "origin": {"align_origin": True},
}


def assert_stats(ours: dict, prefix: str, theirs: dict) -> None:
    for name in STATS:
        assert ours[f"{prefix}_{name}"] == pytest.approx(theirs[name], rel=DIGITS, abs=1e-12), name


# ----------------------------------------------------------------------------- APE


@pytest.mark.parametrize("relation", APE_RELATIONS)
@pytest.mark.parametrize("align", list(EVO_ALIGN))
def test_ape_matches_evo_for_each_pose_relation_and_alignment(pair, relation, align):
    reference, estimate = pair
    ours = evaluate(reference, estimate, align=align, pose_relation=relation)
    theirs = evo_ape(to_evo(reference), to_evo(estimate), EVO_RELATIONS[relation], **EVO_ALIGN[align])
    assert_stats(ours, "ape", theirs.stats)
    assert ours["align"] == align


@pytest.mark.parametrize("align", ["se3", "sim3", "scale"])
def test_n_to_align_matches_evo(pair, align):
    reference, estimate = pair
    ours = evaluate(reference, estimate, align=align, n_to_align=40)
    theirs = evo_ape(to_evo(reference), to_evo(estimate), EVO_RELATIONS["trans_part"], n_to_align=40,
                     **EVO_ALIGN[align])
    assert_stats(ours, "ape", theirs.stats)
    # Fitting on 40 poses only is a different fit: the test would pass vacuously otherwise.
    assert ours["ape_rmse"] != pytest.approx(evaluate(reference, estimate, align=align)["ape_rmse"], rel=1e-3)


def test_evo_switches_give_the_modes(pair):
    reference, estimate = pair
    for switches, mode in (({"align": True}, "se3"), ({"align": True, "correct_scale": True}, "sim3"),
                           ({"correct_scale": True}, "scale"), ({"align_origin": True}, "origin")):
        assert evaluate(reference, estimate, **switches)["align"] == mode
    with pytest.raises(lm.InputError, match="align_origin cannot be combined"):
        evaluate(reference, estimate, align=True, align_origin=True)
    with pytest.raises(lm.InputError, match="n_to_align"):
        evaluate(reference, estimate, align="se3", n_to_align=2)


# ----------------------------------------------------------------------------- RPE


RPE_CASES = [  # (delta, unit, all_pairs)
    (1, "f", False), (7, "f", True), (1.0, "m", False), (2.5, "m", True), (10.0, "d", False), (25.0, "d", True),
    (0.2, "r", False), (0.3, "r", True),
]


@pytest.mark.parametrize("delta, unit, all_pairs", RPE_CASES)
@pytest.mark.parametrize("from_reference", [True, False])
def test_rpe_matches_evo_for_each_delta_unit(pair, delta, unit, all_pairs, from_reference):
    reference, estimate = pair
    ours = evaluate(reference, estimate, align="se3", delta=delta, delta_unit=unit, all_pairs=all_pairs,
                       pairs_from_reference=from_reference)
    theirs = evo_rpe(to_evo(reference), to_evo(estimate), EVO_RELATIONS["trans_part"], delta=delta,
                     delta_unit=EVO_UNITS[unit], all_pairs=all_pairs, pairs_from_reference=from_reference,
                     align=True)
    assert_stats(ours, "rpe", theirs.stats)
    assert ours["rpe_pairs"] == len(theirs.np_arrays["error_array"]) > 3
    rot = evo_rpe(to_evo(reference), to_evo(estimate), EVO_RELATIONS["angle_deg"], delta=delta,
                  delta_unit=EVO_UNITS[unit], all_pairs=all_pairs, pairs_from_reference=from_reference, align=True)
    assert ours["rpe_trans"] == pytest.approx(theirs.stats["rmse"], rel=DIGITS)
    assert ours["rpe_rot"] == pytest.approx(rot.stats["rmse"], rel=DIGITS)


@pytest.mark.parametrize("relation", RPE_RELATIONS)
@pytest.mark.parametrize("align", ["none", "sim3", "origin"])
def test_rpe_matches_evo_for_each_pose_relation(pair, relation, align):
    reference, estimate = pair
    ours = evaluate(reference, estimate, align=align, delta=2.0, delta_unit="m", pose_relation=relation)
    theirs = evo_rpe(to_evo(reference), to_evo(estimate), EVO_RELATIONS[relation], delta=2.0,
                     delta_unit=Unit.meters, pairs_from_reference=True, **EVO_ALIGN[align])
    assert_stats(ours, "rpe", theirs.stats)


# ----------------------------------------------------------------------------- timestamp matching


def _shifted_pair(rng: np.random.Generator, offset: float) -> tuple[Trajectory, Trajectory]:
    reference = smooth_trajectory(rng, n=250)
    estimate = noisy_estimate(rng, reference)
    # The estimate's clock runs `offset` s behind, with jitter, and starts later than the reference.
    stamps = estimate.timestamps - offset + rng.uniform(-0.012, 0.012, size=len(estimate))
    stamps = np.maximum.accumulate(stamps + np.arange(len(stamps)) * 1e-9)
    keep = slice(20, None)
    return reference, Trajectory(stamps[keep], estimate.poses[keep], "estimate")


@pytest.mark.parametrize("offset, max_diff", [(0.0, 0.01), (0.5, 0.01), (0.5, 0.02), (-1.25, 0.015)])
def test_t_offset_and_t_max_diff_match_evo(offset, max_diff):
    rng = np.random.default_rng(7)
    reference, estimate = _shifted_pair(rng, offset)
    ours = evaluate(reference, estimate, align="se3", t_max_diff=max_diff, t_offset=offset)
    evo_ref, evo_est = evo_sync.associate_trajectories(to_evo(reference), to_evo(estimate), max_diff=max_diff,
                                                       offset_2=offset)
    theirs = evo_ape(evo_ref, evo_est, EVO_RELATIONS["trans_part"], align=True)
    assert ours["matched_poses"] == evo_ref.num_poses
    assert_stats(ours, "ape", theirs.stats)


def test_unassociated_trajectories_need_the_matching_options(pair):
    rng = np.random.default_rng(7)
    reference, estimate = _shifted_pair(rng, 0.5)
    with pytest.raises(lm.TrajectoryError, match="associate them first"):
        evaluate(reference, estimate)
    assert evaluate(reference, estimate, t_offset=0.5)["matched_poses"] > 150  # evo's 0.01 s by default


# ----------------------------------------------------------------------------- the CLI


def _cli_options() -> dict[str, list[str]]:
    """{dest: option strings} of `longslam evaluate`."""
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    return {a.dest: a.option_strings for a in sub.choices["evaluate"]._actions if a.option_strings}


def test_cli_and_library_offer_the_same_options():
    options = _cli_options()
    library = [name for name in inspect.signature(evaluate).parameters if name not in ("reference", "estimate")]
    for name in library:
        assert name in options, f"evaluate({name}=...) has no option in `longslam evaluate`"
    for evo_name in ("delta", "delta_unit", "all_pairs", "pose_relation", "align", "align_origin", "correct_scale",
                     "n_to_align", "t_offset", "t_max_diff", "delta_tol", "pairs_from_reference", "plot",
                     "save_plot", "save_results"):
        assert "--" + evo_name.replace("_", "-") in options.get(evo_name, []), evo_name


def test_cli_options_reach_the_figures(tmp_path, capsys):
    rng = np.random.default_rng(7)
    reference, estimate = _shifted_pair(rng, 0.5)
    write_tum(tmp_path / "gt.txt", reference)
    write_tum(tmp_path / "est.txt", estimate)
    argv = ["evaluate", str(tmp_path / "est.txt"), str(tmp_path / "gt.txt"), "--json", "-r", "angle_deg",
            "-d", "20", "-u", "d", "--all-pairs", "-as", "--n-to-align", "150", "--t-offset", "0.5",
            "--t-max-diff", "0.02", "--no-pairs-from-reference", "-t", "0.05"]
    assert main(argv) == 0
    ours = json.loads(capsys.readouterr().out)
    # The stamps written with 9 decimals and read back: the same association as evo's on the files.
    from longslam.io.trajectory_files import read_tum

    ref, est = read_tum(tmp_path / "gt.txt"), read_tum(tmp_path / "est.txt")
    evo_ref, evo_est = evo_sync.associate_trajectories(to_evo(ref), to_evo(est), max_diff=0.02, offset_2=0.5)
    options = dict(align=True, correct_scale=True, n_to_align=150)
    ape = evo_ape(copy.deepcopy(evo_ref), copy.deepcopy(evo_est), EVO_RELATIONS["angle_deg"], **options)
    rpe = evo_rpe(evo_ref, evo_est, EVO_RELATIONS["angle_deg"], delta=20.0, delta_unit=Unit.degrees,
                  rel_delta_tol=0.05, all_pairs=True, pairs_from_reference=False, **options)
    assert_stats(ours, "ape", ape.stats)
    assert_stats(ours, "rpe", rpe.stats)
    assert ours["units"]["ape_rmse"] == ours["units"]["rpe_rmse"] == "deg"
    assert (ours["align"], ours["n_to_align"], ours["rpe_delta_unit"], ours["rpe_pairs_from"]) == \
        ("sim3", 150, "d", "estimate")


@pytest.mark.parametrize("flags, mode", [([], "none"), (["-a"], "se3"), (["--align"], "se3"), (["-as"], "sim3"),
                                         (["-s"], "scale"), (["--align", "sim3"], "sim3"), (["-a", "--align", "sim3"], "sim3"),
                                         (["--align-origin"], "origin")])
def test_cli_alignment_flags_as_evo(pair, tmp_path, capsys, flags, mode):
    reference, estimate = pair
    write_tum(tmp_path / "gt.txt", reference)
    write_tum(tmp_path / "est.txt", estimate)
    assert main(["evaluate", str(tmp_path / "est.txt"), str(tmp_path / "gt.txt"), *flags, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["align"] == mode


def test_cli_refuses_two_alignments(pair, tmp_path, capsys):
    reference, estimate = pair
    write_tum(tmp_path / "gt.txt", reference)
    write_tum(tmp_path / "est.txt", estimate)
    assert main(["evaluate", str(tmp_path / "est.txt"), str(tmp_path / "gt.txt"), "-a", "--align-origin"]) == 2
    assert "align_origin cannot be combined" in capsys.readouterr().err
