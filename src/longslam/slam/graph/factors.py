"""A factor graph over planar poses and wheel biases, for clients that do not speak GTSAM.

`FactorGraph` holds poses (x, y, yaw) keyed by an index (a frame) and 2-vectors keyed by an index
(a block of frames' forward and heading wheel biases), and the factors between them: priors,
between factors with sigmas or a full information matrix (optionally robust), a random walk
between biases, and the wheel-bias factor, GTSAM's only Python factor here: the wheel step
corrected by the bias state of its block,

    predicted = (forward - bias_forward * moving, lateral, yaw - bias_yaw),
    error = Logmap(predicted^-1 * (x1^-1 * x2)).
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np

from longslam.core.geometry import fold_quarter
from longslam.slam.graph import noise
from longslam.slam.graph.solver import Stopping, levenberg_marquardt

X = gtsam.symbol_shorthand.X
B = gtsam.symbol_shorthand.B
AXES = gtsam.symbol("a", 0)  # the building's wall direction (Rot2), modulo 90 degrees


@dataclass(frozen=True)
class WheelStep:
    """One frame's wheel-odometry step in the previous frame's base frame; `moving`: translating
    (the forward bias is added only then)."""

    forward: float
    lateral: float
    yaw: float
    moving: bool


def wheel_error(step: WheelStep, this: gtsam.CustomFactor, values: gtsam.Values, jacobians: list | None) -> np.ndarray:
    keys = this.keys()
    x1, x2 = values.atPose2(keys[0]), values.atPose2(keys[1])
    bias = values.atPoint2(keys[2]) if len(keys) > 2 else np.zeros(2)
    mv = 1.0 if step.moving else 0.0
    th = step.yaw - bias[1]
    pred = gtsam.Pose2(step.forward - bias[0] * mv, step.lateral, th)
    h1, h2 = np.zeros((3, 3), order="F"), np.zeros((3, 3), order="F")
    delta = x1.between(x2, h1, h2)
    hp, hd = np.zeros((3, 3), order="F"), np.zeros((3, 3), order="F")
    err = pred.between(delta, hp, hd)
    e = gtsam.Pose2.Logmap(err)
    if jacobians is not None:
        # Logmap's Jacobian is the identity to first order at the small errors met here.
        jacobians[0] = hd @ h1
        jacobians[1] = hd @ h2
        if len(keys) > 2:
            c, s = np.cos(th), np.sin(th)
            dpred_dbias = np.array([[-mv * c, 0.0], [mv * s, 0.0], [0.0, -1.0]])
            jacobians[2] = hp @ dpred_dbias
    return e


def wall_error(direction: float, this: gtsam.CustomFactor, values: gtsam.Values, jacobians: list | None) -> np.ndarray:
    """A wall seen at `direction` (rad, in the robot's frame) lies along the axes, modulo 90 deg."""
    keys = this.keys()
    theta = values.atPose2(keys[0]).theta()
    axes = values.atRot2(keys[1]).theta()
    e = fold_quarter(theta + direction - axes)
    if jacobians is not None:
        jacobians[0] = np.array([[0.0, 0.0, 1.0]])
        jacobians[1] = np.array([[-1.0]])
    return np.array([e])


def pose_array(values: gtsam.Values, frames: range) -> np.ndarray:
    """The poses of `frames` in `values`, (len(frames), 3) x, y, yaw."""
    out = np.empty((len(frames), 3))
    for row, k in enumerate(frames):
        p = values.atPose2(X(k))
        out[row] = (p.x(), p.y(), p.theta())
    return out


class FactorGraph:
    """Poses and bias vectors with their factors; `solve` runs the solver loop of `solver.py`.

    `graph` and `values` are GTSAM's, for a test that holds them against GTSAM's own optimizer.
    """

    def __init__(self) -> None:
        self.graph = gtsam.NonlinearFactorGraph()
        self.values = gtsam.Values()
        self.dims: dict[int, int] = {}  # each variable's dimension, in insertion order

    # --- variables
    def add_pose(self, k: int, xyyaw: np.ndarray) -> None:
        self.values.insert(X(k), gtsam.Pose2(*xyyaw))
        self.dims[X(k)] = 3

    def add_bias(self, b: int, value: np.ndarray) -> None:
        self.values.insert(B(b), gtsam.Point2(*value))
        self.dims[B(b)] = 2

    # --- factors
    def prior_pose(self, k: int, xyyaw: np.ndarray, sigmas: np.ndarray) -> None:
        self.graph.add(gtsam.PriorFactorPose2(X(k), gtsam.Pose2(*xyyaw), noise.diagonal(sigmas)))

    def add_axes(self, direction: float) -> None:
        """The building's wall direction as a variable (rad), solved with the poses."""
        self.values.insert(AXES, gtsam.Rot2(direction))
        self.dims[AXES] = 1

    def prior_axes(self, direction: float, sigma: float) -> None:
        self.graph.add(gtsam.PriorFactorRot2(AXES, gtsam.Rot2(direction), noise.diagonal(np.array([sigma]))))

    def wall(self, k: int, direction: float, sigma: float, huber: float = 1.0) -> None:
        """Pose k saw a wall at `direction` (rad, robot frame) along the axes (modulo 90 degrees),
        within `sigma`, under a Huber kernel (in stds)."""
        model = noise.robust(noise.diagonal(np.array([sigma])), "huber", huber)
        self.graph.add(
            gtsam.CustomFactor(model, [X(k), AXES], lambda this, v, h, d=float(direction): wall_error(d, this, v, h))
        )

    def prior_bias(self, b: int, value: np.ndarray, sigmas: np.ndarray) -> None:
        self.graph.add(gtsam.PriorFactorPoint2(B(b), gtsam.Point2(*value), noise.diagonal(sigmas)))

    def bias_walk(self, a: int, b: int, sigmas: np.ndarray) -> None:
        """Bias b = bias a, within `sigmas`: the biases vary slowly."""
        self.graph.add(gtsam.BetweenFactorPoint2(B(a), B(b), gtsam.Point2(0.0, 0.0), noise.diagonal(sigmas)))

    def between(
        self,
        i: int,
        j: int,
        delta: np.ndarray,
        *,
        sigmas: np.ndarray | None = None,
        information: np.ndarray | None = None,
        ridge: float = 0.0,
        kernel: str = "none",
        k: float = 1.0,
    ) -> None:
        """Pose j in pose i's frame is `delta`, with diagonal `sigmas` or a 3x3 `information` (body
        dx, dy, dyaw; `ridge` * I added to it), optionally under a robust kernel."""
        model = noise.diagonal(sigmas) if information is None else noise.gaussian(information, ridge)
        self.graph.add(gtsam.BetweenFactorPose2(X(i), X(j), gtsam.Pose2(*delta), noise.robust(model, kernel, k)))

    def wheel(self, i: int, j: int, step: WheelStep, sigmas: np.ndarray, bias: int | None = None) -> None:
        """The wheel step from pose i to pose j, corrected by bias vector `bias` (or as given)."""
        model = noise.diagonal(sigmas)
        if bias is None:
            self.graph.add(
                gtsam.BetweenFactorPose2(X(i), X(j), gtsam.Pose2(step.forward, step.lateral, step.yaw), model)
            )
            return
        self.graph.add(
            gtsam.CustomFactor(
                model, [X(i), X(j), B(bias)], lambda this, v, h, step=step: wheel_error(step, this, v, h)
            )
        )

    # --- solving
    def solve(self, poses: int | range, stop: Stopping) -> tuple[np.ndarray, int]:
        """Poses 0..`poses`-1 (or the keys of a range) optimised, (poses, 3), and the iterations taken."""
        result, taken = levenberg_marquardt(self.graph, self.values, self.dims, stop)
        return pose_array(result, range(poses) if isinstance(poses, int) else poses), taken
