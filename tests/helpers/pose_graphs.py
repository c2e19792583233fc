"""A square route and an odometry that drifts along it, for the pose-graph tests."""

from __future__ import annotations

import numpy as np

from longslam.core.geometry import compose_xyyaw, relative_xyyaw, wrap_angle

ODO_SIGMAS = (0.05, 0.05, 0.01)
LOOP_SIGMAS = (0.05, 0.05, 0.01)


def square_route(side_steps: int = 10, step: float = 1.0) -> np.ndarray:
    """Ground truth: a 10 m square driven counter-clockwise, ending where it started."""
    poses = [(0.0, 0.0, 0.0)]
    x = y = yaw = 0.0
    for _ in range(4):
        for i in range(side_steps):
            x += step * np.cos(yaw)
            y += step * np.sin(yaw)
            if i == side_steps - 1:
                yaw = float(wrap_angle(yaw + np.pi / 2))
            poses.append((x, y, yaw))
    return np.array(poses)


def drifting_odometry(truth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-step deltas with a 3 % scale error and a 0.02 rad/step heading bias, and their integral."""
    deltas = relative_xyyaw(truth[:-1], truth[1:])
    deltas[:, 0] *= 1.03
    deltas[:, 2] += 0.02
    poses = [truth[0]]
    for d in deltas:
        poses.append(compose_xyyaw(poses[-1], d))
    return deltas, np.array(poses)


def as_array(result: dict, n: int) -> np.ndarray:
    return np.array([result[i] for i in range(n)])
