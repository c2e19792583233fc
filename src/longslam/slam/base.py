"""The interface every SLAM method implements: frames in, a pose per frame out, then a result."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from longslam.errors import InputError
from longslam.frame import Frame, Intrinsics
from longslam.gridmap import GridMap
from longslam.trajectory import Trajectory


@dataclass
class Result:
    trajectory: Trajectory  # final estimate, one pose per frame (after any optimisation)
    online: Trajectory  # what `step` returned at each frame
    grid: GridMap | None = None  # 2D occupancy map in the world frame
    cloud: np.ndarray | None = None  # (N, 3) float points of a 3D map, if the method builds one
    # Counts (nodes, submaps, loop closures accepted/rejected...) and bytes held by each map part.
    stats: dict[str, Any] = field(default_factory=dict)


@runtime_checkable
class Method(Protocol):
    name: str

    def step(self, frame: Frame) -> np.ndarray:
        """Take one frame; return the 4x4 camera-in-world pose estimate for it, online."""
        ...

    def finish(self) -> Result:
        """Final trajectory for every frame, maps and stats."""
        ...


@dataclass(frozen=True)
class MethodContext:
    """What a method may know before the first frame: nothing about the simulator."""

    intrinsics: Intrinsics
    max_depth: float | None
    output_dir: str | None = None  # where a method may keep files (e.g. a database)


def frame_odometry(frame: Frame, method: str) -> np.ndarray:
    """The frame's odometry pose as float64, or a clear error for methods fed by odometry
    (real TUM sequences come without it)."""
    if frame.odometry is None:
        raise InputError(
            f"frame {frame.index} (t={frame.timestamp:.6f}) has no odometry pose; the {method!r} method "
            f"needs a sequence with odometry.txt"
        )
    return np.array(frame.odometry, dtype=np.float64)
