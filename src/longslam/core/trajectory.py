"""The trajectory: timestamps plus camera-in-world poses, validated on construction."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from longslam.core.errors import TrajectoryError
from longslam.core.geometry import rigidity_violation

RIGID_TOLERANCE = 1e-4


@dataclass(frozen=True)
class Trajectory:
    timestamps: np.ndarray  # (N,) seconds, strictly increasing
    poses: np.ndarray  # (N, 4, 4) float64 SE(3), camera-in-world
    source: str = ""  # where it came from, named in error messages

    def __post_init__(self) -> None:
        where = f" in {self.source}" if self.source else ""
        stamps = np.asarray(self.timestamps, dtype=np.float64).reshape(-1)
        poses = np.asarray(self.poses, dtype=np.float64)
        if poses.ndim != 3 or poses.shape[1:] != (4, 4):
            raise TrajectoryError(f"poses{where} must have shape (N, 4, 4), got {poses.shape}")
        if len(stamps) != len(poses):
            raise TrajectoryError(f"trajectory{where} has {len(stamps)} timestamps but {len(poses)} poses")
        if not np.all(np.isfinite(stamps)):
            raise TrajectoryError(f"trajectory{where} has non-finite timestamps (NaN or inf)")
        bad = np.flatnonzero(~np.all(np.isfinite(poses), axis=(1, 2)))
        if len(bad):
            raise TrajectoryError(
                f"trajectory{where} has NaN or inf in pose {bad[0]} (t={stamps[bad[0]]:.6f})"
                f"{f' and {len(bad) - 1} more' if len(bad) > 1 else ''}"
            )
        if len(poses):
            violation = rigidity_violation(poses)
            worst = int(np.argmax(violation))
            if violation[worst] > RIGID_TOLERANCE:
                raise TrajectoryError(
                    f"pose {worst} (t={stamps[worst]:.6f}){where} is not a rigid transform "
                    f"(deviation {violation[worst]:.3g}; expected a rotation with det 1 and "
                    f"bottom row 0 0 0 1)"
                )
        if len(stamps) > 1 and np.any(np.diff(stamps) <= 0):
            first = int(np.flatnonzero(np.diff(stamps) <= 0)[0])
            raise TrajectoryError(
                f"timestamps{where} must be strictly increasing; t[{first + 1}]={stamps[first + 1]:.6f} "
                f"follows t[{first}]={stamps[first]:.6f}"
            )
        object.__setattr__(self, "timestamps", stamps)
        object.__setattr__(self, "poses", poses)

    def __len__(self) -> int:
        return len(self.timestamps)

    @property
    def positions(self) -> np.ndarray:
        return self.poses[:, :3, 3]

    def subset(self, indices: np.ndarray) -> "Trajectory":
        return Trajectory(self.timestamps[indices], self.poses[indices], self.source)

    def path_length(self) -> float:
        """Distance travelled, metres."""
        return float(np.linalg.norm(np.diff(self.positions, axis=0), axis=1).sum())

    def distances(self) -> np.ndarray:
        """(N,) distance travelled up to each pose, metres."""
        steps = np.linalg.norm(np.diff(self.positions, axis=0), axis=1)
        return np.concatenate([[0.0], np.cumsum(steps)])
