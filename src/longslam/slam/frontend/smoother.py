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

    def __post_init__(self) -> None:
        if self.optimizer not in self.CHOICES["optimizer"]:
            raise InputError(f"front end: smoother.optimizer must be lm or gn, got {self.optimizer!r}")


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
