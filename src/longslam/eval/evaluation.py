"""One evaluation of an estimate against its reference: the scores, and the arrays behind them
(per-pose APE, per-pair RPE, the aligned estimate) that plots and evo result files need.

The options are evo_ape's / evo_rpe's, under their names (see `longslam evaluate --help`):
alignment (`align`, `correct_scale`, `align_origin`, `n_to_align`), the pose relation, the RPE's
`delta`, `delta_unit`, `all_pairs`, `delta_tol`, `pairs_from_reference`, and timestamp matching
(`t_max_diff`, `t_offset`). Two defaults differ from evo's, so a long route is scored per metre:
RPE pairs are `delta` = 1 m of path apart (evo: 1 frame), chosen on the reference (evo: the
estimate), so an estimate that stalls or jumps does not change which segments are scored.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass
from typing import Any

import numpy as np

from longslam.core.errors import InputError
from longslam.core.trajectory import Trajectory
from longslam.eval.align import alignment, alignment_mode, transform_trajectory
from longslam.eval.metrics import (
    MIN_STEP,
    _local_steps,
    ate,
    delta_unit_letter,
    relative_errors,
    rpe_errors,
    rpe_pairs,
    statistics,
)
from longslam.eval.relations import ape_relation_errors, check_relation, rpe_relation_errors
from longslam.eval.sync import associate, require_same_length

DEFAULT_T_MAX_DIFF = 0.01  # seconds, evo's --t_max_diff default


@dataclass(frozen=True)
class Evaluation:
    scores: dict[str, Any]  # flat and JSON-ready: see `evaluate`
    reference: Trajectory  # associated
    estimate: Trajectory  # associated, as given
    aligned: Trajectory  # the estimate after the alignment (the estimate itself for 'none')
    ape_errors: np.ndarray  # (N,) per pose, under the pose relation
    rpe_errors: np.ndarray | None  # (M,) per pair under the pose relation; None without pairs
    rpe_ids: np.ndarray | None  # (M,) index j of each pair (i, j), as evo's delta_ids
    alignment_sim3: np.ndarray | None  # 4x4 [sR t; 0 1] applied to the estimate, None for 'none'


def _sim3(rotation: np.ndarray, translation: np.ndarray, scale: float) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = scale * rotation
    out[:3, 3] = translation
    return out


def evaluate_full(
    reference: Trajectory,
    estimate: Trajectory,
    align: str | bool = "none",
    delta: float = 1.0,
    min_step: float = MIN_STEP,
    *,
    delta_unit: str = "m",
    all_pairs: bool = False,
    delta_tol: float = 0.1,
    pairs_from_reference: bool = True,
    pose_relation: str = "trans_part",
    correct_scale: bool = False,
    align_origin: bool = False,
    n_to_align: int = -1,
    t_max_diff: float | None = None,
    t_offset: float = 0.0,
) -> Evaluation:
    """`evaluate` with the arrays behind its scores."""
    if t_max_diff is not None or t_offset != 0.0:
        reference, estimate = associate(
            reference, estimate, DEFAULT_T_MAX_DIFF if t_max_diff is None else t_max_diff, t_offset
        )
    require_same_length(reference, estimate, minimum=2)
    if not min_step > 0.0:
        raise InputError(f"min_step must be a length > 0 m, got {min_step}")
    check_relation(pose_relation, "RPE")
    letter = delta_unit_letter(delta_unit)
    if not delta > 0:
        raise InputError(f"RPE delta must be > 0, got {delta}")
    if not delta_tol >= 0:
        raise InputError(f"RPE delta_tol must be >= 0 (a fraction of delta), got {delta_tol}")
    mode = alignment_mode(align, correct_scale, align_origin)

    longest = float(np.linalg.norm(_local_steps(reference.poses), axis=1).max())
    # A slow hand-held sequence at 30 Hz (TUM's freiburg2_xyz moves 2 mm a frame) has no step
    # of min_step: E_trans and E_rot are undefined there, the other metrics are not.
    relative = relative_errors(reference, estimate, min_step) if longest >= min_step else None
    rotation, translation, scale = alignment(estimate, reference, mode, n_to_align)
    aligned = estimate if mode == "none" else transform_trajectory(estimate, rotation, translation, scale)

    # point_distance_error_ratio is an RPE relation only; APE then reports the translation part.
    ape_relation = pose_relation if pose_relation != "point_distance_error_ratio" else "trans_part"
    ape_errors = ape_relation_errors(reference, aligned, ape_relation)
    absolute = statistics(ape_errors)

    chooser = reference if pairs_from_reference else aligned
    first, second = rpe_pairs(chooser, delta, letter, all_pairs, delta_tol)
    rpe_values = rpe_ids = None
    relative_pose: dict[str, float | None] = {}
    if len(first):
        rpe_values, rpe_ids = rpe_relation_errors(reference, aligned, first, second, pose_relation)
        trans, rot = rpe_errors(reference, aligned, first, second)
        relative_pose = {f"rpe_{name}": value for name, value in statistics(rpe_values).items()}
        relative_pose["rpe_trans"] = statistics(trans)["rmse"]
        relative_pose["rpe_rot"] = statistics(rot)["rmse"]
    else:
        # A path shorter than one segment has no RPE (a few seconds of a hand-held sequence).
        relative_pose = {f"rpe_{name}": None for name in ("rmse", "mean", "median", "std", "min", "max")}
        relative_pose.update(rpe_trans=None, rpe_rot=None)

    scores = {
        "ate": ate(reference, estimate),
        "e_trans": None if relative is None else relative.e_trans,
        "e_rot": None if relative is None else relative.e_rot,
        "used_steps": 0 if relative is None else relative.used_steps,
        "skipped_steps": len(reference) - 1 if relative is None else relative.skipped_steps,
        "zero_estimate_steps": 0 if relative is None else relative.zero_estimate_steps,
        **{f"ape_{name}": value for name, value in absolute.items()},
        "rpe_trans": relative_pose.pop("rpe_trans"),
        "rpe_rot": relative_pose.pop("rpe_rot"),
        **relative_pose,
        "rpe_pairs": int(len(first)),
        "rpe_delta": int(delta) if letter == "f" else float(delta),
        "rpe_delta_unit": letter,
        "rpe_all_pairs": bool(all_pairs),
        "rpe_pairs_from": "reference" if pairs_from_reference else "estimate",
        "pose_relation": pose_relation,
        "ape_pose_relation": ape_relation,
        "matched_poses": len(reference),
        "path_length": reference.path_length(),
        "align": mode,
        "align_scale": float(scale),
        "n_to_align": int(n_to_align) if mode not in ("none", "origin") else -1,
    }
    return Evaluation(
        scores,
        reference,
        estimate,
        aligned,
        ape_errors,
        rpe_values,
        rpe_ids,
        None if mode == "none" else _sim3(rotation, translation, scale),
    )


def evaluate(reference: Trajectory, estimate: Trajectory, *args: Any, **options: Any) -> dict:
    """All metrics of one run as a flat, JSON-ready dict (no NaN); units in `longslam.eval.units`.

    The options are `longslam evaluate`'s, which are evo_ape's / evo_rpe's (see
    `longslam.eval.evaluation`): `align` is a mode of `longslam.eval.align.ALIGN_MODES` or True
    (se3); `correct_scale`, `align_origin`, `n_to_align` as evo's; `pose_relation` one of
    `longslam.eval.relations.RPE_RELATIONS`; RPE pairs `delta` apart in `delta_unit` (f frames,
    m metres of path, d / r degrees / radians of rotation), consecutive or `all_pairs` (within
    `delta_tol` * delta), chosen on the reference unless `pairs_from_reference` is False. Given
    `t_max_diff` or `t_offset`, poses are first matched by timestamp (evo's defaults 0.01 s, 0 s);
    otherwise they must be associated already.

    The paper's ate, e_trans, e_rot never use alignment nor the pose relation; e_trans and e_rot
    are None when no ground-truth step moves `min_step` (every step skipped). ape_* (rmse, mean,
    median, std, min, max) and rpe_* are statistics under the pose relation (APE takes trans_part
    for the RPE-only point_distance_error_ratio); rpe_trans (m) and rpe_rot (deg) are always the
    RMSEs of the translation part and the rotation angle over the same pairs. The rpe_ figures
    are None when no pair is found (a path shorter than delta). path_length is the ground
    truth's over the associated poses.
    """
    return evaluate_full(reference, estimate, *args, **options).scores


# The same parameters as evaluate_full, for help() and for the CLI test that holds them together.
evaluate.__signature__ = inspect.signature(evaluate_full).replace(return_annotation=dict)  # type: ignore[attr-defined]  # a function's attribute help() reads
