"""The solver loop of longslam's factor graphs: Levenberg-Marquardt driven from Python.

Undamped (Gauss-Newton) steps while they lower the error, damping raised tenfold when a step
fails or the system is singular, lowered after each good step; the same convergence test as
GTSAM's (relative or absolute decrease of the error).

Not GTSAM's own optimizers for graphs with Python factors (the wheel-bias factor): they pass
their C++-owned Values to each Python CustomFactor, and pybind11 copies a C++-owned const
reference, so every call of every wheel factor would copy the whole trajectory and a pass would
cost O(frames^2); here the Values stay Python-owned and are passed by reference, so a pass is
linear in the frames. A graph of GTSAM factors only (`PoseGraph`) is solved by
GTSAM's own Levenberg-Marquardt in C++ (`gtsam_levenberg_marquardt`).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import gtsam
import numpy as np

LAMBDA_MIN, LAMBDA_MAX, LAMBDA_FACTOR = 1e-5, 1e5, 10.0  # GTSAM's Levenberg-Marquardt defaults


@dataclass(frozen=True)
class Stopping:
    """When the solver loop stops: after `iterations` steps, once a step lowers the error by less
    than `relative_tolerance` of it, or (without `damping`, Gauss-Newton) where a step fails."""

    iterations: int
    relative_tolerance: float
    damping: bool = True


def add_damping(linear: gtsam.GaussianFactorGraph, keys: Iterable[int], dims: dict[int, int], lam: float) -> None:
    """lam * I on each of `keys` (Levenberg-Marquardt's damping), pushed onto `linear`."""
    root = np.sqrt(lam)
    for key in keys:
        dim = dims[key]
        linear.push_back(
            gtsam.JacobianFactor(key, root * np.eye(dim), np.zeros(dim), gtsam.noiseModel.Unit.Create(dim))
        )


def _damped(linear: gtsam.GaussianFactorGraph, dims: dict[int, int], lam: float) -> gtsam.GaussianFactorGraph:
    """The linear system plus lam * I on every variable."""
    damped = linear.clone()
    add_damping(damped, dims, dims, lam)
    return damped


def raised(lam: float) -> float:
    """The damping after a step that failed to lower the error."""
    return max(lam * LAMBDA_FACTOR, LAMBDA_MIN)


def lowered(lam: float) -> float:
    """The damping after a good step."""
    return 0.0 if lam <= LAMBDA_MIN else lam / LAMBDA_FACTOR


def converged(decrease: float, error: float, relative_tolerance: float) -> bool:
    """GTSAM's test after a step that took the error down by `decrease` to `error`."""
    return decrease <= relative_tolerance * (error + decrease) or decrease <= 1e-5


def levenberg_marquardt(
    graph: gtsam.NonlinearFactorGraph,
    values: gtsam.Values,
    dims: dict[int, int],
    stop: Stopping,
) -> tuple[gtsam.Values, int]:
    """The optimised values and the iterations taken. `dims` holds each variable's dimension."""
    error = graph.error(values)
    lam = 0.0
    iteration = 0
    while iteration < stop.iterations:
        linear = graph.linearize(values)
        while True:
            try:
                system = linear if lam == 0.0 else _damped(linear, dims, lam)
                candidate = values.retract(system.optimize())
                new_error = graph.error(candidate)
            except RuntimeError:  # an indeterminate (or nearly so) system: damp it
                new_error = np.inf
            if new_error <= error:
                break
            if not stop.damping or lam >= LAMBDA_MAX:
                return values, iteration  # no step lowers the error any more
            lam = raised(lam)
        iteration += 1
        decrease = error - new_error
        values, error = candidate, new_error
        lam = lowered(lam)
        if converged(decrease, error, stop.relative_tolerance):
            break
    return values, iteration


def gtsam_levenberg_marquardt(
    graph: gtsam.NonlinearFactorGraph, values: gtsam.Values, max_iterations: int
) -> tuple[gtsam.Values, int]:
    """GTSAM's own Levenberg-Marquardt (its default tolerances): the optimised values and the
    iterations taken."""
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(int(max_iterations))
    optimizer = gtsam.LevenbergMarquardtOptimizer(graph, values, params)
    result = optimizer.optimize()
    return result, int(optimizer.iterations())
