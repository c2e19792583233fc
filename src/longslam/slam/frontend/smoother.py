"""The front end's batch estimator over planar poses (x, y, yaw), run at the end.

`FullSmoother` runs over every frame, as a `slam.graph.FactorGraph`: the wheel factors of the
online filter (`filter.py`; lateral step held tight, the biases as slowly varying states, one per block of frames), the scan-to-map
factors (information = the registration's Hessian), and the loop closures a method adds. The
final trajectory comes from it, so a loop correction spreads as smooth curvature.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from longslam.errors import InputError
from longslam.slam.frontend.filter import MotionNoise
from longslam.slam.frontend.frame_store import FrameRecord, FrameStore
from longslam.geometry.planar import compose_xyyaw, relative_xyyaw
from longslam.slam.graph.factors import FactorGraph, WheelStep


# Added to a scan's or loop's information: a registration's Hessian is singular along a corridor.
INFORMATION_RIDGE = 1e-6


@dataclass
class SmootherConfig:
    CHOICES: ClassVar[dict[str, tuple[str, ...]]] = {"optimizer": ("lm", "gn")}  # what `longslam list --params` shows

    bias_block: int = 10  # frames sharing one bias state
    # The wheels' lateral step, held far tighter than online: E_rot scores the direction of each
    # 10 Hz step in the previous pose's frame, and dead reckoning gets that almost exactly right
    # (0.13 deg/m at large noise = 0.05 mm sideways per 15 cm step). A correction must come as
    # heading and forward distance, never as a sideways shift of a step.
    lateral_sigma: float = 1e-5  # m: std of a wheel step's sideways component in the smoother
    # Without wheel odometry, each step's sideways motion (the y of its twist, which is zero on
    # any arc a wheeled base drives) held to this std in metres; 0: off, as for a hand-held camera.
    nonholonomic_sigma: float = 0.0
    iterations: int = 50  # most optimiser iterations of the full smoother
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
    # Most frames in one solve (0: no limit, the default). A longer route is solved window by
    # window, so that the smoother's own memory stays that of one window: each window alone, then
    # the chain of the windows' ends with the loop constraints, then each window with its ends held
    # on the chain. Off by default, as measured on paper-1km-x3 (3 km, large noise, seed 0):
    # window 8,000 gave keyframe ATE 1.47 m against 0.44 m whole, the same peak (615 / 619 MB:
    # the finish's peak is the maps') and a longer finish (41 / 14 s).
    window: int = 0

    def __post_init__(self) -> None:
        if self.optimizer not in self.CHOICES["optimizer"]:
            raise InputError(f"front end: smoother.optimizer must be lm or gn, got {self.optimizer!r}")
        if not self.nonholonomic_sigma >= 0:
            raise InputError(f"front end: smoother.nonholonomic_sigma must be >= 0 m (0: off), got {self.nonholonomic_sigma}")
        if self.window != 0 and self.window < 2 * self.bias_block:
            raise InputError(f"front end: smoother.window must be 0 (no limit) or at least twice bias_block "
                             f"({2 * self.bias_block} frames), got {self.window}")


class FullSmoother:
    """Batch smoother over every frame: a factor graph of slam/graph, solved by its solver loop."""

    def __init__(self, noise: MotionNoise, config: SmootherConfig | None = None, use_bias: bool = True):
        self.noise = noise
        self.config = config or SmootherConfig()
        self.use_bias = use_bias
        # Every frame's online pose (`initial`) and factors (`records`), in flat arrays.
        self.records = FrameStore()
        self.initial = self.records.poses
        self.loops: list[tuple[int, int, np.ndarray, np.ndarray]] = []
        # (frame, wall direction in the robot's frame, std): walls along the building's axes, whose
        # direction is solved with the poses from `axes_initial` (wall_axes.py).
        self.walls: list[tuple[int, float, float]] = []
        self.axes_initial = 0.0
        self.bias_init: dict[int, np.ndarray] = {}

    def add_frame(self, online_pose: np.ndarray, wheel: WheelStep | None, wheel_sigmas: np.ndarray | None,
                  cv_step: np.ndarray | None, scan: tuple[int, np.ndarray, np.ndarray] | None,
                  bias: np.ndarray | None, visual: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        k = len(self.records)
        self.records.append(np.asarray(online_pose, dtype=np.float64),
                            FrameRecord(wheel, wheel_sigmas, cv_step, scan, visual, bias))
        block = k // self.config.bias_block
        if bias is not None and block not in self.bias_init:
            self.bias_init[block] = np.asarray(bias, dtype=np.float64).copy()

    def add_wall(self, k: int, direction: float, sigma: float) -> None:
        """Frame k saw a wall at `direction` (rad, robot frame) along the building's axes."""
        self.walls.append((int(k), float(direction), float(sigma)))

    def add_loop(self, i: int, j: int, delta: np.ndarray, information: np.ndarray) -> None:
        self.loops.append((int(i), int(j), np.asarray(delta, dtype=np.float64), np.asarray(information, dtype=np.float64)))

    def solve(self) -> np.ndarray:
        """Every frame's smoothed base pose (x, y, yaw), (frames, 3)."""
        n = len(self.initial)
        if n == 0:
            return np.zeros((0, 3))
        window = self.config.window
        if window == 0 or n <= window:
            out, self.iterations = self._solve(self.build_graph(), 0, n - 1)
            return out
        return self._solve_in_windows(window)

    def _solve(self, graph: FactorGraph, first: int, last: int) -> tuple[np.ndarray, int]:
        return graph.solve(range(first, last + 1), iterations=self.config.iterations,
                           relative_tolerance=self.config.relative_tolerance, damping=self.config.optimizer != "gn")

    def _solve_in_windows(self, window: int) -> np.ndarray:
        """Window by window, so that no solve holds more than `window` frames:

        1. each window alone (its frames' factors and the loops inside it), from its start's online
           pose;
        2. the skeleton (`_skeleton`): the windows' ends and every loop constraint's two frames,
           chained by the first solves' steps between them, with the loop constraints;
        3. each window again, from its first solve moved onto the skeleton, its two ends held at
           the skeleton's poses, and each loop constraint with one frame in it tying that frame to
           the other frame's skeleton pose (held there), with the constraint's own information."""
        n = len(self.initial)
        ends = list(range(0, n - 1, window - 1)) + [n - 1]
        first_pass = np.empty((n, 3))
        self.iterations = 0
        for a, b in zip(ends[:-1], ends[1:]):
            first_pass[a:b + 1], taken = self._solve(self.build_graph(a, b), a, b)
            self.iterations = max(self.iterations, taken)
        skeleton = self._skeleton(ends, first_pass)
        out = np.empty((n, 3))
        for a, b in zip(ends[:-1], ends[1:]):
            moved = np.array([compose_xyyaw(skeleton[a], relative_xyyaw(first_pass[a], p)) for p in first_pass[a:b + 1]])
            graph = self.build_graph(a, b, fixed={a: skeleton[a], b: skeleton[b]}, initial=moved)
            held: set[int] = set()
            for i, j, delta, info in self.loops:
                if (a <= i <= b) != (a <= j <= b):  # the frame outside is held at its skeleton pose
                    outside = j if a <= i <= b else i
                    if outside not in held:
                        held.add(outside)
                        graph.add_pose(outside, skeleton[outside])
                        graph.prior_pose(outside, skeleton[outside], np.array([1e-4, 1e-4, 1e-5]))
                    graph.between(i, j, delta, information=info, ridge=INFORMATION_RIDGE)
            out[a:b + 1], taken = self._solve(graph, a, b)
            self.iterations = max(self.iterations, taken)
        return out

    def _skeleton(self, ends: list[int], first_pass: np.ndarray) -> dict[int, np.ndarray]:
        """Poses of the windows' ends and of every loop constraint's frames: a chain of the first
        pass's steps between consecutive ones (each within one window; sigmas from
        `_chain_sigmas`), and the loop constraints between their own frames."""
        nodes = sorted(set(ends) | {f for i, j, _, _ in self.loops for f in (i, j)})
        node_of = {k: node for node, k in enumerate(nodes)}
        graph = FactorGraph()
        for node, k in enumerate(nodes):
            graph.add_pose(node, first_pass[k])
        graph.prior_pose(0, self.initial[0], np.array([1e-4, 1e-4, 1e-5]))
        for node, (p, q) in enumerate(zip(nodes[:-1], nodes[1:])):
            graph.between(node, node + 1, relative_xyyaw(first_pass[p], first_pass[q]), sigmas=self._chain_sigmas(p, q))
        for i, j, delta, info in self.loops:
            graph.between(node_of[i], node_of[j], delta, information=info, ridge=INFORMATION_RIDGE)
        poses, _ = graph.solve(range(len(nodes)), iterations=self.config.iterations,
                               relative_tolerance=self.config.relative_tolerance, damping=True)
        return {k: poses[node] for node, k in enumerate(nodes)}

    def _chain_sigmas(self, a: int, b: int) -> np.ndarray:
        """Sigmas of a window's step from frame a to frame b: each frame's step sigmas (wheel and
        visual combined as independent measurements, or the constant-velocity ones), their
        variances summed, a heading variance turned into sideways variance over the distance still
        to go, and the wheel biases' prior uncertainty over the window. An approximation of the
        window's marginal, on the loose side: only the chain of the windows' ends uses it."""
        nz = self.noise
        variance = np.zeros(3)
        for k in range(a + 1, b + 1):
            rec = self.records[k]
            sources = []
            if rec.wheel_sigmas is not None:
                sources.append(np.asarray(rec.wheel_sigmas, dtype=np.float64) ** 2)
            elif rec.cv_step is not None:
                sources.append(np.array([nz.cv_forward, nz.cv_lateral, nz.cv_yaw]) ** 2)
            if rec.visual is not None:
                sources.append(np.asarray(rec.visual[1], dtype=np.float64) ** 2)
            if not sources:
                continue
            step = 1.0 / np.sum([1.0 / np.maximum(v, 1e-18) for v in sources], axis=0)
            remaining = float(np.hypot(*(self.initial[b][:2] - self.initial[k][:2])))
            variance += step + np.array([0.0, step[2] * remaining ** 2, 0.0])
        # A window alone may not see its wheel biases (nothing but the loops ties its heading):
        # its step carries their uncertainty, once per frame, fully correlated.
        frames, length = b - a, float(np.hypot(*(self.initial[b][:2] - self.initial[a][:2])))
        yaw = frames * nz.bias_yaw_init
        variance += np.array([(frames * nz.bias_forward_init) ** 2, (yaw * length / 2.0) ** 2, yaw ** 2])
        return np.sqrt(np.maximum(variance, 1e-12))

    def build_graph(self, first: int = 0, last: int | None = None, fixed: dict[int, np.ndarray] | None = None,
                    initial: np.ndarray | None = None) -> FactorGraph:
        """The factor graph over frames `first`..`last` (default every frame), from the online
        poses (or `initial`, one per frame of the range): held at the start's online pose, or at
        the `fixed` poses (a window's ends)."""
        n = len(self.initial)
        last = n - 1 if last is None else last
        nz = self.noise
        graph = FactorGraph()
        for k in range(first, last + 1):
            start = self.initial[k] if initial is None else initial[k - first]
            graph.add_pose(k, start if fixed is None or k not in fixed else fixed[k])
        for k, pose in (fixed or {first: self.initial[first]}).items():
            graph.prior_pose(k, pose, np.array([1e-4, 1e-4, 1e-5]))
        blocks_used: set[int] = set()
        for k in range(first + 1, last + 1):
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
            if rec.wheel is None and self.config.nonholonomic_sigma > 0:
                # The step's twist (Logmap of the relative pose) has no sideways part: forward and
                # turn are left free (a std of 1 km and 1000 rad), only y is held.
                graph.between(k - 1, k, np.zeros(3), sigmas=np.array([1e3, self.config.nonholonomic_sigma, 1e3]))
            if rec.visual is not None:
                step, sigmas = rec.visual
                graph.between(k - 1, k, step, sigmas=sigmas)
            if rec.scan is not None and rec.scan[0] >= first:
                anchor, meas, info = rec.scan
                graph.between(anchor, k, meas, information=info, ridge=INFORMATION_RIDGE)
        if blocks_used:
            blocks = sorted(blocks_used)
            value = np.zeros(2)
            for b in range(blocks[0], blocks[-1] + 1):
                value = self.bias_init.get(b, value)
                graph.add_bias(b, value)
            # The route's first block starts from no bias; a later window's, from the online filter's.
            start = np.zeros(2) if first == 0 else self.bias_init.get(blocks[0], np.zeros(2))
            graph.prior_bias(blocks[0], start, np.array([nz.bias_forward_init, nz.bias_yaw_init]))
            walk = np.sqrt(self.config.bias_block) * np.array([nz.bias_forward_walk, nz.bias_yaw_walk])
            for b in range(blocks[0], blocks[-1]):
                graph.bias_walk(b, b + 1, walk)
        for i, j, delta, info in self.loops:
            if first <= i <= last and first <= j <= last:
                graph.between(i, j, delta, information=info, ridge=INFORMATION_RIDGE)
        walls = [w for w in self.walls if first <= w[0] <= last]
        if walls:
            graph.add_axes(self.axes_initial)
            for k, direction, sigma in walls:
                graph.wall(k, direction, sigma)
        return graph
