"""Pairing the poses of two trajectories before they are compared.

`associate` matches by timestamp the way evo's `sync.associate_trajectories` does (nearest stamp,
within `max_diff`, starting from the trajectory with fewer poses so none of its poses is lost), but
always one-to-one: evo can pair two close stamps of the shorter trajectory with the same pose of
the longer one, which would give a trajectory with a repeated timestamp. `associate_by_index` is for
KITTI files, which carry no timestamps.
"""

from __future__ import annotations

from longslam.core.errors import InputError, TrajectoryError
from longslam.core.timestamps import one_to_one_nearest
from longslam.core.trajectory import Trajectory

# Fewer matches than this fraction of the shorter trajectory means the stamps are in different
# clocks or units (or the offset is wrong), not that a few frames were dropped.
MIN_MATCHED_FRACTION = 0.5


def _name(trajectory: Trajectory, default: str) -> str:
    return f"{default} ({trajectory.source})" if trajectory.source else default


def require_same_length(reference: Trajectory, estimate: Trajectory, minimum: int = 1) -> None:
    """Raise TrajectoryError unless both trajectories hold the same number (>= minimum) of poses."""
    if len(reference) != len(estimate):
        raise TrajectoryError(
            f"{_name(reference, 'reference')} has {len(reference)} poses but "
            f"{_name(estimate, 'estimate')} has {len(estimate)}; associate them first "
            f"(longslam.eval.sync.associate, or associate_by_index for KITTI files)"
        )
    if len(reference) < minimum:
        raise TrajectoryError(f"need at least {minimum} associated poses, got {len(reference)}")


def associate(
    reference: Trajectory, estimate: Trajectory, max_diff: float = 0.01, offset: float = 0.0
) -> tuple[Trajectory, Trajectory]:
    """Reduce both trajectories to their poses with matching timestamps.

    `offset` (seconds) is added to the estimate's stamps for matching only; both returned
    trajectories keep their own stamps. Raises TrajectoryError if fewer than half of the
    shorter trajectory's poses find a match.
    """
    if not max_diff >= 0.0:
        raise InputError(f"max_diff must be a time difference >= 0 s, got {max_diff}")
    # evo starts from the trajectory with fewer poses (the estimate on a tie) and shifts the
    # other one's stamps; doing the same keeps the rounding, and so the matches, identical.
    estimate_short = len(estimate) <= len(reference)
    if estimate_short:
        est_idx, ref_idx = one_to_one_nearest(estimate.timestamps, reference.timestamps - offset, max_diff)
    else:
        ref_idx, est_idx = one_to_one_nearest(reference.timestamps, estimate.timestamps + offset, max_diff)

    shorter = min(len(reference), len(estimate))
    if shorter == 0 or len(ref_idx) < MIN_MATCHED_FRACTION * shorter:
        which = "estimate" if estimate_short else "reference"
        raise TrajectoryError(
            f"only {len(ref_idx)} of {shorter} poses of the shorter trajectory ({which}) matched a "
            f"timestamp of the other within max_diff {max_diff} s (offset {offset} s); need at "
            f"least half. Reference stamps span {_span(reference)}, estimate stamps span "
            f"{_span(estimate)}: check that both use the same clock and units, or raise max_diff"
        )
    return reference.subset(ref_idx), estimate.subset(est_idx)


def _span(trajectory: Trajectory) -> str:
    if not len(trajectory):
        return "nothing (no poses)"
    return f"{trajectory.timestamps[0]:.6f}..{trajectory.timestamps[-1]:.6f} s"


def associate_by_index(reference: Trajectory, estimate: Trajectory) -> tuple[Trajectory, Trajectory]:
    """Pair pose i with pose i (KITTI files have no stamps); the lengths must be equal."""
    if len(reference) != len(estimate):
        raise TrajectoryError(
            f"cannot pair poses by index: {_name(reference, 'reference')} has {len(reference)} "
            f"poses and {_name(estimate, 'estimate')} has {len(estimate)}. Files without "
            f"timestamps (KITTI) must hold one pose per frame, for the same frames"
        )
    return reference, estimate
