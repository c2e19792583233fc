"""Trajectory error metrics: the paper's (ATE, E_trans, E_rot) and the field's (APE, RPE as in evo).

Every function takes associated trajectories (same length, pose i of one matched with pose i of
the other; see `longslam.eval.sync`) and returns plain floats, arrays or JSON-ready dicts.
Rotation errors are reported in degrees, like the paper and evo's `rotation_angle_deg`.

The paper's metrics (reference/paper_setup.md), with p_t the ground-truth pose, p~_t the estimate,
and a_t = M(p_{t-1})^-1 p_t the ground-truth step expressed in the previous pose's frame:
    ATE     = mean_t ||p_t - p~_t||                         (positions, no alignment)
    E_trans = mean_t ||a_t - a~_t|| / ||p_t - p_{t-1}||      (unitless)
    E_rot   = mean_t angle(a_t, a~_t) / ||p_t - p_{t-1}||    (degrees per metre)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from longslam.core.errors import InputError, TrajectoryError, UnknownNameError
from longslam.core.geometry import invert
from longslam.core.trajectory import Trajectory
from longslam.eval.align import align_trajectory
from longslam.eval.angle_pairs import pairs_by_angle
from longslam.eval.pairs import consecutive_pairs
from longslam.eval.sync import require_same_length

MIN_STEP = 0.01  # metres: ground-truth steps shorter than this are turning in place
# An estimated step shorter than this has no direction: positions written with 9 decimals cannot
# resolve less, so anything below is rounding noise, not motion.
ZERO_STEP = 1e-9
# Angle given to a step whose estimate has no direction: 90 degrees is the mean angle between a
# fixed vector and a uniformly random direction, so a stalled estimate is neither rewarded (0) nor
# treated as having driven backwards (180). Its E_trans term is 1 (the whole step is missed).
ZERO_STEP_ANGLE_DEG = 90.0

PARTS = ("translation", "rotation")


# ----------------------------------------------------------------------------- helpers


def rotation_angle_deg(rotations: np.ndarray) -> np.ndarray:
    """Rotation angle in degrees of (..., 3, 3) rotation matrices.

    atan2 of the skew part's norm (2 sin a) and trace - 1 (2 cos a) stays accurate near 0 and
    180 degrees, where arccos of the trace loses half the digits; evo (via scipy) is accurate
    there too, and the tests compare to 1e-9.
    """
    r = np.asarray(rotations, dtype=np.float64)
    skew = np.stack([r[..., 2, 1] - r[..., 1, 2], r[..., 0, 2] - r[..., 2, 0], r[..., 1, 0] - r[..., 0, 1]], axis=-1)
    trace = np.trace(r, axis1=-2, axis2=-1)
    return np.degrees(np.arctan2(np.linalg.norm(skew, axis=-1), trace - 1.0))


def statistics(errors: np.ndarray) -> dict[str, float]:
    """rmse, mean, median, std (population, as evo), min and max of an error array."""
    errors = np.asarray(errors, dtype=np.float64)
    if not len(errors):
        raise TrajectoryError("no errors to summarise (empty error array)")
    return {
        "rmse": float(np.sqrt(np.mean(errors**2))),
        "mean": float(np.mean(errors)),
        "median": float(np.median(errors)),
        "std": float(np.std(errors)),
        "min": float(np.min(errors)),
        "max": float(np.max(errors)),
    }


def _check_name(kind: str, value: str, valid: tuple[str, ...]) -> None:
    if value not in valid:
        raise UnknownNameError(kind, value, valid)


def _local_steps(poses: np.ndarray) -> np.ndarray:
    """(N-1, 3) M(p_{t-1})^-1 p_t: each position in the frame of the pose before it."""
    displacement = poses[1:, :3, 3] - poses[:-1, :3, 3]
    return np.einsum("nji,nj->ni", poses[:-1, :3, :3], displacement)


# ----------------------------------------------------------------------------- the paper's metrics


def ate(reference: Trajectory, estimate: Trajectory) -> float:
    """Mean position error in metres, without alignment (the paper's ATE)."""
    require_same_length(reference, estimate)
    return float(np.mean(np.linalg.norm(estimate.positions - reference.positions, axis=1)))


@dataclass(frozen=True)
class RelativeErrors:
    """The paper's E_trans and E_rot, with their per-step terms for plots.

    Step t (1..N-1) goes from pose t-1 to pose t. Steps whose ground-truth displacement is under
    `min_step` are left out of both means and counted in `skipped_steps`. The arrays hold one
    entry per used step.
    """

    e_trans: float  # unitless (metres of error per metre travelled)
    e_rot: float  # degrees per metre
    used_steps: int
    skipped_steps: int
    zero_estimate_steps: int  # used steps where the estimate did not move (angle set to 90 deg)
    steps: np.ndarray  # (M,) index t of each used step
    distance: np.ndarray  # (M,) ground-truth distance travelled up to pose t, metres
    step_e_trans: np.ndarray  # (M,) ||a_t - a~_t|| / ||p_t - p_{t-1}||
    step_e_rot: np.ndarray  # (M,) angle(a_t, a~_t) / ||p_t - p_{t-1}||, degrees per metre


def relative_errors(reference: Trajectory, estimate: Trajectory, min_step: float = MIN_STEP) -> RelativeErrors:
    """The paper's E_trans and E_rot between associated ground truth and estimate (no alignment).

    Raises TrajectoryError if no ground-truth step is at least `min_step` long.
    """
    if not min_step > 0.0:
        # A step of zero length cannot be divided by: it must always be skipped.
        raise InputError(f"min_step must be a length > 0 m, got {min_step}")
    require_same_length(reference, estimate, minimum=2)
    true_step = _local_steps(reference.poses)
    est_step = _local_steps(estimate.poses)
    # |a_t| equals ||p_t - p_{t-1}|| since rotations keep lengths.
    length = np.linalg.norm(true_step, axis=1)
    used = length >= min_step
    if not np.any(used):
        raise TrajectoryError(
            f"none of the {len(length)} ground-truth steps moves at least min_step = {min_step} m "
            f"(longest {length.max():.3g} m), so E_trans and E_rot are undefined"
        )
    true_step, est_step, length = true_step[used], est_step[used], length[used]

    step_e_trans = np.linalg.norm(true_step - est_step, axis=1) / length
    angle = np.degrees(
        np.arctan2(
            np.linalg.norm(np.cross(true_step, est_step), axis=1),
            np.einsum("ni,ni->n", true_step, est_step),
        )
    )
    stalled = np.linalg.norm(est_step, axis=1) < ZERO_STEP
    angle[stalled] = ZERO_STEP_ANGLE_DEG
    step_e_rot = angle / length

    steps = np.flatnonzero(used) + 1
    return RelativeErrors(
        e_trans=float(np.mean(step_e_trans)),
        e_rot=float(np.mean(step_e_rot)),
        used_steps=int(used.sum()),
        skipped_steps=int((~used).sum()),
        zero_estimate_steps=int(stalled.sum()),
        steps=steps,
        distance=reference.distances()[steps],
        step_e_trans=step_e_trans,
        step_e_rot=step_e_rot,
    )


# ----------------------------------------------------------------------------- APE (evo's definition)


def ape_errors(reference: Trajectory, estimate: Trajectory, part: str = "translation") -> np.ndarray:
    """(N,) absolute error per pose: metres ('translation') or degrees ('rotation'), no alignment."""
    _check_name("APE part", part, PARTS)
    require_same_length(reference, estimate)
    if part == "translation":
        return np.linalg.norm(estimate.positions - reference.positions, axis=1)
    # evo: angle of est^-1 ref.
    return rotation_angle_deg(np.swapaxes(estimate.poses[:, :3, :3], 1, 2) @ reference.poses[:, :3, :3])


def ape(
    reference: Trajectory, estimate: Trajectory, align: str = "none", part: str = "translation"
) -> dict[str, float]:
    """APE statistics like `evo_ape` (-a for align='se3', -as for 'sim3').

    part 'translation' (metres, evo's translation_part) or 'rotation' (degrees, rotation_angle_deg).
    """
    _check_name("APE part", part, PARTS)
    return statistics(ape_errors(reference, align_trajectory(estimate, reference, align), part))


# ----------------------------------------------------------------------------- RPE (evo's definition)


def pairs_by_index(n: int, delta: int, all_pairs: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (i, j) delta frames apart, as evo's `filters.filter_pairs_by_index`.

    Consecutive: 0-d, d-2d, ...; all pairs: every (i, i + d).
    """
    if delta < 1:
        raise InputError(f"delta in frames must be at least 1, got {delta}")
    if all_pairs:
        first = np.arange(max(n - delta, 0))
        return first, first + delta
    ids = np.arange(0, n, delta)
    return ids[:-1], ids[1:]


def pairs_by_path(
    positions: np.ndarray, delta: float, tol: float = 0.0, all_pairs: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (i, j) about `delta` metres of travelled path apart, as evo's `filter_pairs_by_path`.

    Consecutive: from pose 0, the next pose whose path since the last chosen one reaches delta.
    All pairs: for each i, the j > i whose path from i is nearest delta (the first on a tie),
    kept if within `tol`.
    """
    positions = np.asarray(positions, dtype=np.float64)
    displacement = positions[1:] - positions[:-1]
    if all_pairs:
        step = np.linalg.norm(displacement, axis=1)
        return _all_pairs_by_path(np.concatenate([[0.0], np.cumsum(step)]), delta, tol)
    # evo takes np.linalg.norm of one vector at a time (a dot product); the row-wise norm sums the
    # squares in another order and differs in the last bit for about 1 step in 10. A stacked
    # matmul goes through the same dot kernel.
    step = np.sqrt((displacement[:, None, :] @ displacement[:, :, None])[:, 0, 0])
    return consecutive_pairs(step, delta)


def _all_pairs_by_path(distances: np.ndarray, delta: float, tol: float) -> tuple[np.ndarray, np.ndarray]:
    n = len(distances)
    first = np.arange(n - 1)
    if not len(first):
        return first, first
    # The path from i, distances[j] - distances[i], grows with j, so the j nearest delta is next to
    # where it crosses delta; a few neighbours cover rounding. Each candidate is moved to the start
    # of its run of equal distances (standing still), because evo's argmin takes the first.
    crossing = np.searchsorted(distances, distances[first] + delta, side="left")
    candidates = crossing[:, None] + np.arange(-2, 2)[None, :]
    candidates = np.clip(candidates, first[:, None] + 1, n - 1)
    run_start = np.searchsorted(distances, distances[candidates], side="left")
    candidates = np.maximum(run_start, first[:, None] + 1)
    # Same expression as evo, so ties and the tolerance test round the same way.
    miss = np.abs((distances[candidates] - distances[first][:, None]) - delta)
    # Candidates are in increasing order, so argmin takes the smallest index on a tie, as evo's.
    best = np.argmin(miss, axis=1)
    best_miss = miss[first, best]
    best_j = candidates[first, best]
    keep = best_miss <= tol
    return first[keep], best_j[keep]


def rpe_errors(
    reference: Trajectory,
    estimate: Trajectory,
    first: np.ndarray,
    second: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Per pair, RPE translation (metres) and rotation angle (degrees) of
    E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j), Q the reference and P the estimate (evo's rpe_base)."""
    ref_rel = invert(reference.poses[first]) @ reference.poses[second]
    est_rel = invert(estimate.poses[first]) @ estimate.poses[second]
    error = invert(ref_rel) @ est_rel
    return np.linalg.norm(error[:, :3, 3], axis=1), rotation_angle_deg(error[:, :3, :3])


DELTA_UNITS = ("f", "m", "d", "r")  # evo_rpe's -u: frames, metres of path, degrees, radians of rotation
_DELTA_UNIT_NAMES = {"frames": "f", "f": "f", "m": "m", "d": "d", "r": "r"}
DELTA_UNIT_LABELS = {"f": "frames", "m": "m", "d": "deg", "r": "rad"}


def delta_unit_letter(unit: str) -> str:
    """evo's letter (f, m, d, r) for a delta unit; 'frames' is accepted for 'f'."""
    if unit not in _DELTA_UNIT_NAMES:
        raise UnknownNameError("RPE delta unit", unit, (*DELTA_UNITS, "frames"))
    return _DELTA_UNIT_NAMES[unit]


def rpe_pairs(
    chooser: Trajectory, delta: float, unit: str = "m", all_pairs: bool = False, rel_tol: float = 0.1
) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs of `chooser` `delta` apart in `unit` (evo's `id_pairs_from_delta`)."""
    letter = delta_unit_letter(unit)
    if not delta > 0:
        raise InputError(f"RPE delta must be > 0, got {delta}")
    if letter == "f":
        if float(delta) != int(delta):
            raise InputError(f"RPE delta in frames must be a whole number, got {delta}")
        return pairs_by_index(len(chooser), int(delta), all_pairs)
    if letter == "m":
        return pairs_by_path(chooser.positions, delta, delta * rel_tol, all_pairs)
    return pairs_by_angle(chooser.poses[:, :3, :3], delta, delta * rel_tol, letter == "d", all_pairs)


def _no_pairs(chooser: Trajectory, delta: float, unit: str, which: str) -> TrajectoryError:
    return TrajectoryError(
        f"RPE with delta {delta} {DELTA_UNIT_LABELS[delta_unit_letter(unit)]} found no pair of poses on the "
        f"{which} ({len(chooser)} poses, {chooser.path_length():.3f} m of path); use a smaller delta"
    )


def rpe(
    reference: Trajectory,
    estimate: Trajectory,
    delta: float = 1.0,
    unit: str = "m",
    all_pairs: bool = False,
    rel_tol: float = 0.1,
    pairs_from_reference: bool = False,
) -> dict:
    """RPE like `evo_rpe` (no alignment; align first with `longslam.eval.align` if wanted).

    delta in metres of travelled path (unit 'm'), frames ('f' or 'frames'), or degrees / radians
    of rotation ('d', 'r'). Pairs are chosen on the estimate's poses, as evo does by default, or on
    the reference's with `pairs_from_reference` (evo's --pairs_from_reference). In all_pairs mode
    (units m, d, r) pairs off delta by more than rel_tol * delta are dropped. Returns
    {'translation': stats (m), 'rotation': stats (deg), 'pairs': count, 'delta': delta, 'unit':
    unit}. Other pose relations: `evaluate(..., pose_relation=...)`.
    """
    require_same_length(reference, estimate, minimum=2)
    chooser = reference if pairs_from_reference else estimate
    if delta_unit_letter(unit) == "f" and float(delta) == int(delta):
        delta = int(delta)
    first, second = rpe_pairs(chooser, delta, unit, all_pairs, rel_tol)
    if not len(first):
        raise _no_pairs(chooser, delta, unit, "reference" if pairs_from_reference else "estimate")
    translation, rotation = rpe_errors(reference, estimate, first, second)
    return {
        "translation": statistics(translation),
        "rotation": statistics(rotation),
        "pairs": int(len(first)),
        "delta": delta,
        "unit": unit,
    }


# ----------------------------------------------------------------------------- summaries


def errors_by_distance(
    reference: Trajectory, estimate: Trajectory, align: str = "none"
) -> tuple[np.ndarray, np.ndarray]:
    """(N,) ground-truth distance travelled (m) and (N,) position error (m) at each pose."""
    aligned = align_trajectory(estimate, reference, align)
    return reference.distances(), ape_errors(reference, aligned, "translation")
