"""The two estimators of the front end over planar poses (x, y, yaw).

`BiasFilter` runs online, one frame at a time: an extended Kalman filter over the pose and the
two wheel biases of the noise model (metres per frame added to the forward step while the
robot translates; radians per frame added to the heading change), which is the fixed-lag
smoother of lag one. Its pose feeds the local map and is what `step` returns.

`FullSmoother` runs at the end, over every frame, as a `slam.graph.FactorGraph`: the same wheel factors (lateral
step held tight, the biases as slowly varying states, one per block of frames), the scan-to-map
factors (information = the registration's Hessian), and the loop closures a method adds. The
final trajectory comes from it, so a loop correction spreads as smooth curvature.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from longslam.geometry import compose_xyyaw, wrap_angle
from longslam.slam.graph.factors import FactorGraph, WheelStep


@dataclass(frozen=True)
class MotionNoise:
    """Per-frame noise of the wheel step and of its biases (stds)."""

    forward_min: float = 0.003  # m
    forward_rel: float = 0.01  # fraction of the forward step
    lateral: float = 0.001  # m: wheels do not slip sideways
    yaw_min: float = 0.0005  # rad
    yaw_rel: float = 0.01  # fraction of the heading change
    # Bias random walks per frame: the biases hold for seconds, so they move little per frame,
    # yet fast enough to follow a new value within a few seconds.
    bias_forward_walk: float = 0.0008  # m/frame per frame
    bias_yaw_walk: float = 0.00003  # rad/frame per frame
    bias_forward_init: float = 0.01  # m/frame
    bias_forward_reset: float = 0.03  # m/frame, added when the RGB-D steps say the bias jumped
    bias_yaw_init: float = 0.0005  # rad/frame
    # Without wheels: a constant-velocity prediction, loose in every direction.
    cv_forward: float = 0.05  # m
    cv_lateral: float = 0.02  # m
    cv_yaw: float = 0.03  # rad


class BiasFilter:
    """EKF over [x, y, yaw, forward bias, yaw bias]."""

    def __init__(self, pose: np.ndarray, noise: MotionNoise, use_bias: bool = True):
        self.noise = noise
        self.use_bias = use_bias
        self.state = np.zeros(5)
        self.state[:3] = pose
        self.cov = np.diag([1e-8, 1e-8, 1e-10, noise.bias_forward_init ** 2, noise.bias_yaw_init ** 2])

    @property
    def pose(self) -> np.ndarray:
        return self.state[:3].copy()

    @property
    def bias(self) -> np.ndarray:
        return self.state[3:].copy()

    def predict_wheel(self, step: WheelStep) -> None:
        n = self.noise
        mv = 1.0 if step.moving else 0.0
        b = self.state[3:] if self.use_bias else np.zeros(2)
        f, l, dth = step.forward - b[0] * mv, step.lateral, step.yaw - b[1]
        sigmas = np.array([n.forward_min + n.forward_rel * abs(f), n.lateral, n.yaw_min + n.yaw_rel * abs(dth)])
        jac_bias = np.array([[-mv, 0.0], [0.0, 0.0], [0.0, -1.0]]) if self.use_bias else np.zeros((3, 2))
        walk = np.array([n.bias_forward_walk, n.bias_yaw_walk]) if self.use_bias else np.zeros(2)
        self._predict(np.array([f, l, dth]), sigmas, jac_bias, walk)

    def predict_constant_velocity(self, step: np.ndarray) -> None:
        n = self.noise
        self._predict(np.asarray(step, dtype=np.float64), np.array([n.cv_forward, n.cv_lateral, n.cv_yaw]),
                      np.zeros((3, 2)), np.zeros(2))

    def _predict(self, delta: np.ndarray, sigmas: np.ndarray, jac_bias: np.ndarray, walk: np.ndarray) -> None:
        th = self.state[2]
        c, s = np.cos(th), np.sin(th)
        g = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])  # body step -> world
        f_mat = np.eye(5)
        f_mat[0, 2] = -s * delta[0] - c * delta[1]
        f_mat[1, 2] = c * delta[0] - s * delta[1]
        f_mat[:3, 3:] = g @ jac_bias
        q = np.zeros((5, 5))
        q[:3, :3] = g @ np.diag(sigmas ** 2) @ g.T
        q[3:, 3:] = np.diag(walk ** 2)
        self.state[:3] = compose_xyyaw(self.state[:3], delta)
        self.cov = f_mat @ self.cov @ f_mat.T + q

    def predict_step(self, step: np.ndarray, sigmas: np.ndarray) -> None:
        """A measured step (e.g. visual) with its stds, when there are no wheels."""
        self._predict(np.asarray(step, dtype=np.float64), np.asarray(sigmas, dtype=np.float64), np.zeros((3, 2)), np.zeros(2))

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
        gain = self.cov @ h.T @ np.linalg.inv(s)
        self.state += gain @ (z - h @ self.state)
        self.state[2] = wrap_angle(self.state[2])
        self.cov = (np.eye(5) - gain @ h) @ self.cov
        self.cov = 0.5 * (self.cov + self.cov.T)

    def widen_forward_bias(self, std: float) -> None:
        """The forward bias may have jumped: add `std`^2 to its variance."""
        self.cov[3, 3] += std ** 2

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


# Added to a scan's or loop's information: a registration's Hessian is singular along a corridor.
INFORMATION_RIDGE = 1e-6


@dataclass
class SmootherConfig:
    bias_block: int = 10  # frames sharing one bias state
    # The wheels' lateral step, held far tighter than online: E_rot scores the direction of each
    # 10 Hz step in the previous pose's frame, and dead reckoning gets that almost exactly right
    # (0.13 deg/m at large noise = 0.05 mm sideways per 15 cm step). A correction must come as
    # heading and forward distance, never as a sideways shift of a step.
    lateral_sigma: float = 1e-5  # m
    iterations: int = 50
    # Bias states in the smoother (a Python factor per frame), or each wheel step corrected by
    # the online filter's bias estimate (GTSAM's own between factors).
    bias_states: bool = True
    # "lm": Levenberg-Marquardt (Gauss-Newton steps, damped when one fails); "gn": stop there instead.
    optimizer: str = "lm"
    # Measured on paper-300m xlarge seed 2 (with GTSAM's own optimizer, not the loop of
    # slam/graph/solver.py):
    # 1e-5 took 27 iterations for ATE 0.567 m; 3e-4 takes 5 for 0.580 m. Without bias states
    # 0.590 m.
    relative_tolerance: float = 3e-4


@dataclass
class _Record:
    wheel: WheelStep | None
    wheel_sigmas: np.ndarray | None
    cv_step: np.ndarray | None  # constant-velocity prediction used without wheels
    scan: tuple[int, np.ndarray, np.ndarray] | None  # anchor frame, relative measurement, body information
    visual: tuple[np.ndarray, np.ndarray] | None = None  # step from the previous frame, its stds
    bias: np.ndarray | None = None  # the online filter's wheel biases after this frame


class FullSmoother:
    """Batch smoother over every frame: a factor graph of slam/graph, solved by its solver loop."""

    def __init__(self, noise: MotionNoise, config: SmootherConfig | None = None, use_bias: bool = True):
        self.noise = noise
        self.config = config or SmootherConfig()
        self.use_bias = use_bias
        self.initial: list[np.ndarray] = []
        self.records: list[_Record] = []
        self.loops: list[tuple[int, int, np.ndarray, np.ndarray]] = []
        self.bias_init: dict[int, np.ndarray] = {}

    def add_frame(self, online_pose: np.ndarray, wheel: WheelStep | None, wheel_sigmas: np.ndarray | None,
                  cv_step: np.ndarray | None, scan: tuple[int, np.ndarray, np.ndarray] | None,
                  bias: np.ndarray | None, visual: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        k = len(self.initial)
        self.initial.append(np.asarray(online_pose, dtype=np.float64).copy())
        self.records.append(_Record(wheel, wheel_sigmas, cv_step, scan, visual,
                                    None if bias is None else np.asarray(bias, dtype=np.float64).copy()))
        block = k // self.config.bias_block
        if bias is not None and block not in self.bias_init:
            self.bias_init[block] = np.asarray(bias, dtype=np.float64).copy()

    def add_loop(self, i: int, j: int, delta: np.ndarray, information: np.ndarray) -> None:
        self.loops.append((int(i), int(j), np.asarray(delta, dtype=np.float64), np.asarray(information, dtype=np.float64)))

    def solve(self) -> np.ndarray:
        """Every frame's smoothed base pose (x, y, yaw), (frames, 3)."""
        n = len(self.initial)
        if n == 0:
            return np.zeros((0, 3))
        out, self.iterations = self.build_graph().solve(
            n, iterations=self.config.iterations, relative_tolerance=self.config.relative_tolerance,
            damping=self.config.optimizer != "gn")
        return out

    def build_graph(self) -> FactorGraph:
        """The factor graph over every frame, with its initial values."""
        n = len(self.initial)
        nz = self.noise
        graph = FactorGraph()
        for k, p in enumerate(self.initial):
            graph.add_pose(k, p)
        graph.prior_pose(0, self.initial[0], np.array([1e-4, 1e-4, 1e-5]))
        blocks_used: set[int] = set()
        for k in range(1, n):
            rec = self.records[k]
            if rec.wheel is not None:
                sig = np.array(rec.wheel_sigmas, dtype=np.float64)
                sig[1] = min(sig[1], self.config.lateral_sigma)
                step = rec.wheel
                if self.use_bias and self.config.bias_states:
                    block = (k - 1) // self.config.bias_block
                    blocks_used.add(block)
                    graph.wheel(k - 1, k, step, sig, bias=block)
                else:
                    # The step corrected by the online filter's biases: a plain GTSAM factor.
                    b = rec.bias if (self.use_bias and rec.bias is not None) else np.zeros(2)
                    corrected = WheelStep(step.forward - (b[0] if step.moving else 0.0), step.lateral, step.yaw - b[1], step.moving)
                    graph.wheel(k - 1, k, corrected, sig)
            elif rec.cv_step is not None:
                graph.between(k - 1, k, rec.cv_step, sigmas=np.array([nz.cv_forward, nz.cv_lateral, nz.cv_yaw]))
            if rec.visual is not None:
                step, sigmas = rec.visual
                graph.between(k - 1, k, step, sigmas=sigmas)
            if rec.scan is not None:
                anchor, meas, info = rec.scan
                graph.between(anchor, k, meas, information=info, ridge=INFORMATION_RIDGE)
        if blocks_used:
            blocks = sorted(blocks_used)
            last = np.zeros(2)
            for b in range(blocks[0], blocks[-1] + 1):
                last = self.bias_init.get(b, last)
                graph.add_bias(b, last)
            graph.prior_bias(blocks[0], np.zeros(2), np.array([nz.bias_forward_init, nz.bias_yaw_init]))
            walk = np.sqrt(self.config.bias_block) * np.array([nz.bias_forward_walk, nz.bias_yaw_walk])
            for b in range(blocks[0], blocks[-1]):
                graph.bias_walk(b, b + 1, walk)
        for i, j, delta, info in self.loops:
            graph.between(i, j, delta, information=info, ridge=INFORMATION_RIDGE)
        return graph
