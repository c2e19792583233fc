"""The odometry noise drawn along a route: the paper's bias model (`longslam.core.odometry_noise`)
applied to the true motion, from a seeded generator."""

from __future__ import annotations

import math

import numpy as np

from longslam.core.geometry import wrap_angle
from longslam.core.odometry_noise import BiasNoise

# Below this forward step (metres) a frame counts as turning in place: no linear bias is added.
TRANSLATING_STEP = 1e-4


def apply_noise(noise: BiasNoise, timestamps: np.ndarray, xyyaw: np.ndarray, rng: np.random.Generator) -> np.ndarray:
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
    epoch = np.floor((np.asarray(timestamps[:-1]) - timestamps[0]) / noise.redraw_period).astype(np.int64)
    n_epochs = int(epoch.max()) + 1 if len(epoch) else 0
    lin_bias = rng.normal(0.0, noise.linear_std, n_epochs) if noise.linear_std > 0 else np.zeros(n_epochs)
    ang_bias = rng.normal(0.0, noise.angular_std_deg, n_epochs) if noise.angular_std_deg > 0 else np.zeros(n_epochs)
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
