"""The odometry noise model of the paper, with its units made explicit.

Per frame, the odometry integrates the true motion plus two biases: a linear bias (metres per
frame) added to the forward step on frames where the robot translates, and an angular bias
(degrees per frame) added to the heading change on every frame. Both are drawn from zero-mean
Gaussians with the level's std and redrawn every `redraw_period` seconds of simulated time.
The odometry starts at the true first pose.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from longslam.geometry import wrap_angle
from longslam.core.registry import Registry

# Below this forward step (metres) a frame counts as turning in place: no linear bias is added.
TRANSLATING_STEP = 1e-4


@dataclass(frozen=True)
class BiasNoise:
    name: str
    linear_std: float  # metres per frame
    angular_std_deg: float  # degrees per frame
    redraw_period: float = 10.0  # seconds

    def apply(self, timestamps: np.ndarray, xyyaw: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """True (N, 3) x, y, yaw base poses at `timestamps` -> noisy odometry (N, 3)."""
        xyyaw = np.asarray(xyyaw, dtype=np.float64)
        n = len(xyyaw)
        if n == 0:
            return xyyaw.copy()
        # True per-frame motion in the robot's own frame at the previous pose.
        d_world = np.diff(xyyaw[:, :2], axis=0)
        c, s = np.cos(xyyaw[:-1, 2]), np.sin(xyyaw[:-1, 2])
        forward = c * d_world[:, 0] + s * d_world[:, 1]
        lateral = -s * d_world[:, 0] + c * d_world[:, 1]
        dyaw = wrap_angle(np.diff(xyyaw[:, 2]))

        # The bias of step k (from frame k to k+1) is the one in force at frame k's time.
        epoch = np.floor((np.asarray(timestamps[:-1]) - timestamps[0]) / self.redraw_period).astype(np.int64)
        n_epochs = int(epoch.max()) + 1 if len(epoch) else 0
        lin_bias = rng.normal(0.0, self.linear_std, n_epochs) if self.linear_std > 0 else np.zeros(n_epochs)
        ang_bias = rng.normal(0.0, self.angular_std_deg, n_epochs) if self.angular_std_deg > 0 else np.zeros(n_epochs)
        translating = np.abs(forward) > TRANSLATING_STEP
        forward_noisy = forward + np.where(translating, lin_bias[epoch], 0.0)
        dyaw_noisy = dyaw + np.radians(ang_bias[epoch])

        out = np.empty_like(xyyaw)
        out[0] = xyyaw[0]
        x, y, yaw = map(float, xyyaw[0])
        for k in range(n - 1):
            ck, sk = math.cos(yaw), math.sin(yaw)
            x += ck * forward_noisy[k] - sk * lateral[k]
            y += sk * forward_noisy[k] + ck * lateral[k]
            yaw = float(wrap_angle(yaw + dyaw_noisy[k]))
            out[k + 1] = (x, y, yaw)
        return out

    def step_variances(self) -> tuple[float, float]:
        """Variances of one frame's odometry error that this model implies: (forward step in m^2,
        heading change in rad^2), in the robot's frame at the start of the step.

        The forward error of a step is the linear bias in force (zero-mean, std `linear_std`), the
        heading error the angular bias (std `angular_std_deg`, in radians here); the lateral step
        and the height carry no error. The biases are held for `redraw_period` seconds, so the
        errors of the steps inside one period are not independent: the error of n consecutive
        steps inside a period has n^2 times these variances (not n times), and steps in different
        periods are independent.
        """
        return self.linear_std**2, math.radians(self.angular_std_deg) ** 2


NOISE_LEVELS: Registry[BiasNoise] = Registry("noise level")
for _level in (
    BiasNoise("none", 0.0, 0.0),
    BiasNoise("small", 0.0015, 0.003),
    BiasNoise("medium", 0.003, 0.0075),
    BiasNoise("large", 0.0075, 0.015),
    BiasNoise("xlarge", 0.015, 0.025),
):
    NOISE_LEVELS.register(_level.name, _level)


def get_noise(name: str) -> BiasNoise:
    return NOISE_LEVELS.get(name)
