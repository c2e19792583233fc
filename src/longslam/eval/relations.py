"""evo's pose relations: which number an absolute or relative pose error is reduced to.

The names are evo_ape's / evo_rpe's `--pose_relation` choices, and each is computed as evo's
`metrics.APE` / `metrics.RPE` compute it, so the figures agree with evo's to rounding:

    trans_part       ||translation of E||                          metres
    rot_part         ||R(E) - I|| (Frobenius)                      unitless
    full             ||E - I|| (Frobenius, 4x4)                    unitless
    angle_deg        rotation angle of E                           degrees
    angle_rad        rotation angle of E                           radians
    point_distance   APE: as trans_part; RPE: | |q_j - q_i| - |p_j - p_i| |    metres
    point_distance_error_ratio   RPE only: point_distance / |q_j - q_i| * 100   percent

E is est^-1 ref for APE (evo's ape_base) and (Q_i^-1 Q_j)^-1 (P_i^-1 P_j) for RPE (rpe_base).
"""

from __future__ import annotations

import numpy as np

from longslam.core.errors import InputError, UnknownNameError
from longslam.core.geometry import invert
from longslam.core.trajectory import Trajectory

APE_RELATIONS = ("trans_part", "rot_part", "full", "angle_deg", "angle_rad", "point_distance")
RPE_RELATIONS = APE_RELATIONS + ("point_distance_error_ratio",)
RELATION_UNITS = {
    "trans_part": "m",
    "rot_part": "",
    "full": "",
    "angle_deg": "deg",
    "angle_rad": "rad",
    "point_distance": "m",
    "point_distance_error_ratio": "%",
}
# evo's PoseRelation values, which evo writes into a result's title.
EVO_NAMES = {
    "trans_part": "translation part",
    "rot_part": "rotation part",
    "full": "full transformation",
    "angle_deg": "rotation angle in degrees",
    "angle_rad": "rotation angle in radians",
    "point_distance": "point distance",
    "point_distance_error_ratio": "point distance error ratio",
}


def check_relation(relation: str, kind: str = "RPE") -> str:
    valid = APE_RELATIONS if kind == "APE" else RPE_RELATIONS
    if relation not in valid:
        raise UnknownNameError(f"{kind} pose relation", relation, valid)
    return relation


def rotation_angle_rad(rotations: np.ndarray) -> np.ndarray:
    """Rotation angle in radians of (..., 3, 3) matrices; atan2 keeps it accurate near 0 and pi."""
    r = np.asarray(rotations, dtype=np.float64)
    skew = np.stack([r[..., 2, 1] - r[..., 1, 2], r[..., 0, 2] - r[..., 2, 0], r[..., 1, 0] - r[..., 0, 1]], axis=-1)
    return np.arctan2(np.linalg.norm(skew, axis=-1), np.trace(r, axis1=-2, axis2=-1) - 1.0)


def _reduce(error: np.ndarray, relation: str) -> np.ndarray:
    """(N,) numbers of (N, 4, 4) error poses for a relation that needs the whole pose."""
    if relation == "trans_part":
        return np.linalg.norm(error[:, :3, 3], axis=1)
    if relation == "rot_part":
        return np.linalg.norm(error[:, :3, :3] - np.eye(3), axis=(1, 2))
    if relation == "full":
        return np.linalg.norm(error - np.eye(4), axis=(1, 2))
    angle = rotation_angle_rad(error[:, :3, :3])
    return np.degrees(angle) if relation == "angle_deg" else angle


def ape_relation_errors(reference: Trajectory, estimate: Trajectory, relation: str = "trans_part") -> np.ndarray:
    """(N,) absolute pose error per pose under `relation` (associated trajectories, no alignment)."""
    check_relation(relation, "APE")
    if relation in ("trans_part", "point_distance"):
        return np.linalg.norm(estimate.positions - reference.positions, axis=1)
    return _reduce(invert(estimate.poses) @ reference.poses, relation)


def rpe_relation_errors(
    reference: Trajectory, estimate: Trajectory, first: np.ndarray, second: np.ndarray, relation: str = "trans_part"
) -> tuple[np.ndarray, np.ndarray]:
    """Relative pose error per pair (first[k], second[k]) under `relation`, and the pairs' `second`
    indices kept (point_distance_error_ratio drops pairs whose reference distance is 0, as evo)."""
    check_relation(relation, "RPE")
    if relation in ("point_distance", "point_distance_error_ratio"):
        ref_distance = np.linalg.norm(reference.positions[first] - reference.positions[second], axis=1)
        est_distance = np.linalg.norm(estimate.positions[first] - estimate.positions[second], axis=1)
        error = np.abs(ref_distance - est_distance)
        if relation == "point_distance":
            return error, second
        nonzero = ref_distance != 0
        if not np.any(nonzero):
            raise InputError(
                "point_distance_error_ratio: every pair's reference distance is 0 (a reference standing still)"
            )
        return error[nonzero] / ref_distance[nonzero] * 100, second[nonzero]
    ref_rel = invert(reference.poses[first]) @ reference.poses[second]
    est_rel = invert(estimate.poses[first]) @ estimate.poses[second]
    return _reduce(invert(ref_rel) @ est_rel, relation), second
