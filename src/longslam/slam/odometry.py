"""Dead reckoning: the odometry's own poses. The floor every SLAM method must beat."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from longslam.core.frame import Frame
from longslam.core.trajectory import Trajectory
from longslam.slam import stats
from longslam.slam.api import MethodContext, MethodSpec, Result, frame_odometry


@dataclass(frozen=True)
class OdometryConfig:
    """Dead reckoning has no parameters."""


class OdometryMethod:
    name = "odometry"

    def __init__(self, context: MethodContext, config: OdometryConfig = OdometryConfig()):
        self.config = config
        self._stamps: list[float] = []
        self._poses: list[np.ndarray] = []

    def step(self, frame: Frame) -> np.ndarray:
        pose = frame_odometry(frame, self.name)
        self._stamps.append(frame.timestamp)
        self._poses.append(pose)
        return pose

    def finish(self) -> Result:
        poses = np.array(self._poses).reshape(-1, 4, 4)
        trajectory = Trajectory(np.array(self._stamps), poses, source="odometry")
        return Result(trajectory=trajectory, online=trajectory, stats={stats.MAP_BYTES: {}, stats.FRAMES: len(poses)})


SPEC = MethodSpec("odometry", OdometryConfig, OdometryMethod, "dead reckoning: the odometry's own poses")
