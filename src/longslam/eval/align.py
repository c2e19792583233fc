"""Aligning an estimated trajectory to the reference: Umeyama's least-squares SE(3) / Sim(3) fit.

Same definition as evo's `geometry.umeyama_alignment` and `PosePath3D.align` (positions only; the
fitted transform is then applied to whole poses), so aligned APE agrees with `evo_ape -a / -as`.
The modes, with evo_ape's options beside them:

    none    no alignment                                 (evo: no option)
    se3     rotation and translation                     (-a / --align)
    sim3    rotation, translation and scale              (-as / --align --correct_scale)
    scale   scale only, positions multiplied by s        (-s / --correct_scale)
    origin  the first pose moved onto the reference's    (--align_origin)

`n_to_align` fits on the first n poses only (evo's --n_to_align); -1 means all.
"""

from __future__ import annotations

import numpy as np

from longslam.core.errors import InputError, UnknownNameError
from longslam.core.geometry import invert
from longslam.core.geometry.fit import umeyama  # noqa: F401  (re-exported: evaluation's alignment)
from longslam.core.trajectory import Trajectory
from longslam.eval.sync import require_same_length

ALIGN_MODES = ("none", "se3", "sim3", "scale", "origin")


def alignment_mode(align: str | bool = "none", correct_scale: bool = False, align_origin: bool = False) -> str:
    """One of ALIGN_MODES from evo's switches: `align` (a mode name, or True for se3),
    `correct_scale` (se3 -> sim3, none -> scale) and `align_origin`."""
    mode = {True: "se3", False: "none"}[align] if isinstance(align, bool) else align
    if mode not in ALIGN_MODES:
        raise UnknownNameError("alignment mode", str(mode), ALIGN_MODES)
    if align_origin:
        if mode not in ("none", "origin") or correct_scale:
            # evo refuses the same: an origin alignment and a least-squares one contradict.
            raise InputError(
                f"align_origin cannot be combined with align={mode!r}"
                f"{' and correct_scale' if correct_scale else ''}; choose one alignment"
            )
        return "origin"
    if correct_scale:
        if mode == "origin":
            raise InputError("correct_scale cannot be combined with an origin alignment; choose one")
        return {"none": "scale", "se3": "sim3"}.get(mode, mode)
    return mode


def transform_trajectory(
    trajectory: Trajectory, rotation: np.ndarray, translation: np.ndarray, scale: float = 1.0
) -> Trajectory:
    """Apply x -> s R x + t to every position and R to every orientation (evo: scale, then transform)."""
    poses = trajectory.poses.copy()
    poses[:, :3, :3] = rotation @ trajectory.poses[:, :3, :3]
    poses[:, :3, 3] = scale * trajectory.positions @ rotation.T + translation
    return Trajectory(trajectory.timestamps, poses, trajectory.source)


def alignment(
    estimate: Trajectory, reference: Trajectory, mode: str, n_to_align: int = -1
) -> tuple[np.ndarray, np.ndarray, float]:
    """The (R, t, s) that `align_trajectory` applies for `mode` (identity for 'none'; for 'scale'
    R and t are the identity and s the Sim(3) fit's scale, as evo's correct_only_scale)."""
    if mode not in ALIGN_MODES:
        raise UnknownNameError("alignment mode", mode, ALIGN_MODES)
    require_same_length(reference, estimate)
    if mode == "none":
        return np.eye(3), np.zeros(3), 1.0
    if mode == "origin":
        # evo's align_origin: T = ref_0 est_0^-1, applied to every pose from the left.
        to_origin = reference.poses[0] @ invert(estimate.poses[0])
        return to_origin[:3, :3], to_origin[:3, 3], 1.0
    n = _checked_n(n_to_align, len(estimate))
    rotation, translation, scale = umeyama(
        estimate.positions[:n], reference.positions[:n], with_scale=mode in ("sim3", "scale")
    )
    if mode == "scale":
        return np.eye(3), np.zeros(3), scale
    return rotation, translation, scale


def _checked_n(n_to_align: int, length: int) -> int:
    if n_to_align == -1:
        return length
    if isinstance(n_to_align, bool) or not isinstance(n_to_align, (int, np.integer)) or n_to_align < 3:
        raise InputError(f"n_to_align must be -1 (all poses) or a whole number >= 3, got {n_to_align!r}")
    if n_to_align > length:
        raise InputError(f"n_to_align {n_to_align} is more than the {length} associated poses")
    return int(n_to_align)


def align_trajectory(estimate: Trajectory, reference: Trajectory, mode: str, n_to_align: int = -1) -> Trajectory:
    """The estimate moved (and for 'sim3' / 'scale' scaled) onto the associated reference.

    mode: one of ALIGN_MODES (see the module's docstring); 'none' returns it unchanged.
    """
    rotation, translation, scale = alignment(estimate, reference, mode, n_to_align)
    if mode == "none":
        return estimate
    return transform_trajectory(estimate, rotation, translation, scale)
