"""Dead reckoning: the odometry's own poses. The floor every SLAM method must beat."""

from __future__ import annotations

from typing import Any

import numpy as np

from longslam.errors import InputError
from longslam.frame import Frame
from longslam.slam.base import MethodContext, Result, frame_odometry
from longslam.slam.registry import METHODS
from longslam.trajectory import Trajectory


class OdometryMethod:
    name = "odometry"

    def __init__(self, context: MethodContext, params: dict[str, Any]):
        if params:
            raise InputError(f"method 'odometry' takes no parameters, got {', '.join(sorted(params))}")
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
        return Result(trajectory=trajectory, online=trajectory, stats={"map_bytes": {}, "frames": len(poses)})


METHODS.register("odometry", OdometryMethod)
