"""The front end's online estimator: an extended Kalman filter over the planar pose (x, y, yaw)
and the two wheel biases of the noise model (metres per frame added to the forward step while
the robot translates; radians per frame added to the heading change), one frame at a time: the
fixed-lag smoother of lag one. Its pose feeds the local map and is what `FrontEnd.step` returns.
`MotionNoise` holds the noise of the wheel step and of its biases, for the filter and for the
full smoother (`smoother.py`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from longslam.core.geometry import compose_xyyaw, wrap_angle
from longslam.core.parameter import check_declared, param
from longslam.slam.graph.factors import WheelStep


@dataclass(frozen=True)
class MotionNoise:
    """Per-frame noise of the wheel step and of its biases (stds)."""

    forward_min: float = param(0.003, "floor of a wheel step's forward std", above=0, unit="m")
    forward_rel: float = param(0.01, "forward std as a fraction of the forward step", at_least=0)
    lateral: float = param(0.001, "lateral std of a wheel step (wheels do not slip sideways)", above=0, unit="m")
    yaw_min: float = param(0.0005, "floor of a wheel step's heading std", above=0, unit="rad")
    yaw_rel: float = param(0.01, "heading std as a fraction of the heading change", at_least=0)
    # The biases hold for seconds, so they move little per frame, yet fast enough to follow a new
    # value within a few seconds.
    bias_forward_walk: float = param(
        0.0008, "random walk of the forward bias per frame", above=0, unit="m/frame per frame"
    )
    bias_yaw_walk: float = param(3e-5, "random walk of the heading bias per frame", above=0, unit="rad/frame per frame")
    bias_forward_init: float = param(0.01, "std of the forward bias at the start", above=0, unit="m/frame")
    bias_forward_reset: float = param(
        0.03, "std added to the forward bias when the RGB-D steps say it jumped", at_least=0, unit="m/frame"
    )
    bias_yaw_init: float = param(0.0005, "std of the heading bias at the start", above=0, unit="rad/frame")
    # Without wheels: a constant-velocity prediction, loose in every direction.
    cv_forward: float = param(
        0.05, "forward std of a step predicted at constant velocity (no wheels)", above=0, unit="m"
    )
    cv_lateral: float = param(
        0.02, "lateral std of a step predicted at constant velocity (no wheels)", above=0, unit="m"
    )
    cv_yaw: float = param(0.03, "heading std of a step predicted at constant velocity (no wheels)", above=0, unit="rad")

    def __post_init__(self) -> None:
        check_declared(self, "front end", "noise.")


class BiasFilter:
    """EKF over [x, y, yaw, forward bias, yaw bias]."""

    def __init__(self, pose: np.ndarray, noise: MotionNoise, use_bias: bool = True):
        self.noise = noise
        self.use_bias = use_bias
        self.state = np.zeros(5)
        self.state[:3] = pose
        self.cov = np.diag([1e-8, 1e-8, 1e-10, noise.bias_forward_init**2, noise.bias_yaw_init**2])

    @property
    def pose(self) -> np.ndarray:
        return self.state[:3].copy()

    def place(self, pose: np.ndarray) -> None:
        """Put the pose at `pose` (the first wheel odometry pose), its covariance and the biases
        as they are."""
        self.state[:3] = pose

    @property
    def forward_bias_variance(self) -> float:
        return float(self.cov[3, 3])

    @property
    def bias(self) -> np.ndarray:
        return self.state[3:].copy()

    def predict_wheel(self, step: WheelStep) -> None:
        n = self.noise
        mv = 1.0 if step.moving else 0.0
        b = self.state[3:] if self.use_bias else np.zeros(2)
        f, lat, dth = step.forward - b[0] * mv, step.lateral, step.yaw - b[1]
        sigmas = np.array([n.forward_min + n.forward_rel * abs(f), n.lateral, n.yaw_min + n.yaw_rel * abs(dth)])
        jac_bias = np.array([[-mv, 0.0], [0.0, 0.0], [0.0, -1.0]]) if self.use_bias else np.zeros((3, 2))
        walk = np.array([n.bias_forward_walk, n.bias_yaw_walk]) if self.use_bias else np.zeros(2)
        self._predict(np.array([f, lat, dth]), sigmas, jac_bias, walk)

    def predict_constant_velocity(self, step: np.ndarray) -> None:
        n = self.noise
        self._predict(
            np.asarray(step, dtype=np.float64),
            np.array([n.cv_forward, n.cv_lateral, n.cv_yaw]),
            np.zeros((3, 2)),
            np.zeros(2),
        )

    def _predict(self, delta: np.ndarray, sigmas: np.ndarray, jac_bias: np.ndarray, walk: np.ndarray) -> None:
        th = self.state[2]
        c, s = np.cos(th), np.sin(th)
        g = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])  # body step -> world
        f_mat = np.eye(5)
        f_mat[0, 2] = -s * delta[0] - c * delta[1]
        f_mat[1, 2] = c * delta[0] - s * delta[1]
        f_mat[:3, 3:] = g @ jac_bias
        q = np.zeros((5, 5))
        q[:3, :3] = g @ np.diag(sigmas**2) @ g.T
        q[3:, 3:] = np.diag(walk**2)
        self.state[:3] = compose_xyyaw(self.state[:3], delta)
        self.cov = f_mat @ self.cov @ f_mat.T + q

    def predict_step(self, step: np.ndarray, sigmas: np.ndarray) -> None:
        """A measured step (e.g. visual) with its stds, when there are no wheels."""
        self._predict(
            np.asarray(step, dtype=np.float64), np.asarray(sigmas, dtype=np.float64), np.zeros((3, 2)), np.zeros(2)
        )

    def update_bias(self, residual: np.ndarray, variances: np.ndarray, moving: bool) -> None:
        """Fuse (wheel step - visual step) in forward and yaw, which measures the two biases.

        The forward part is used only while translating: in place, no forward bias is added.
        Through the filter's pose-bias covariance the pose moves with the corrected bias.
        """
        rows = [0, 1] if moving else [1]
        h = np.zeros((len(rows), 5))
        for i, r in enumerate(rows):
            h[i, 3 + r] = 1.0
        z = np.asarray(residual, dtype=np.float64)[rows]
        s = h @ self.cov @ h.T + np.diag(np.asarray(variances)[rows])
        self._correct(self.cov @ h.T @ np.linalg.inv(s), h, z - h @ self.state)

    def update_heading(self, yaw: float, sigma: float) -> None:
        """Fuse a measurement of the heading alone (rad, within `sigma`): the walls' direction."""
        h = np.zeros((1, 5))
        h[0, 2] = 1.0
        s = float(self.cov[2, 2]) + sigma**2
        self._correct(self.cov @ h.T / s, h, np.array([wrap_angle(yaw - self.state[2])]))

    def _correct(self, gain: np.ndarray, h: np.ndarray, innovation: np.ndarray) -> None:
        """The Kalman correction of the state and covariance by `gain` (5, m) for measurement
        rows `h` (m, 5) and their innovation (m,)."""
        self.state += gain @ innovation
        self.state[2] = wrap_angle(self.state[2])
        self.cov = (np.eye(5) - gain @ h) @ self.cov
        self.cov = 0.5 * (self.cov + self.cov.T)

    def widen_forward_bias(self, std: float) -> None:
        """The forward bias may have jumped: add `std`^2 to its variance."""
        self.cov[3, 3] += std**2

    def pose_information(self) -> np.ndarray:
        """Information of the marginal pose (world x, y, yaw): the prior of the registration."""
        return np.linalg.inv(self.cov[:3, :3])

    def update_pose(self, joint_pose: np.ndarray, scan_hessian: np.ndarray) -> None:
        """Fuse a scan-to-map result solved jointly with this filter's pose prior.

        The joint optimum z of prior (x, P) and scan term (H) satisfies
        P^-1 (z - x) + H (z - z_scan) = 0, so H (z_scan - x) = (H + P^-1)(z - x): the scan's
        information vector is known even where H is singular (along a corridor).
        """
        d = np.asarray(joint_pose, dtype=np.float64) - self.state[:3]
        d[2] = wrap_angle(d[2])
        info_vec = (scan_hessian + self.pose_information()) @ d
        lam = np.linalg.inv(self.cov)
        lam[:3, :3] += scan_hessian
        cov = np.linalg.inv(lam)
        cov = 0.5 * (cov + cov.T)
        self.state += cov[:, :3] @ info_vec
        self.state[2] = wrap_angle(self.state[2])
        self.cov = cov
