"""Levenberg-Marquardt over a graph too long to hold at once, one part at a time, with the steps
the whole graph's solve takes.

A route's graph is cut into parts (windows of frames; `build(p)` makes part p's factors, each
factor in exactly one part). A variable that factors of two parts touch is shared: a window's
first frame's step reaches back into the window before, a scan into its anchor's window, a loop
into the other frame's. Each step:

1. each part linearised and its own variables eliminated (GTSAM's partial elimination), which
   leaves a Gaussian factor on the part's shared variables, its Schur complement;
2. the shared variables' step from those factors together;
3. each part linearised again and its own variables' step found by back-substitution, given the
   shared ones'.

In exact arithmetic that is the step of the whole linear system (the same Gauss-Newton step, the
same damping), so the result is the whole solve's but for rounding, while no more than one part's
linear system is held with the shared one. The price is each part built and linearised twice a
step (the error comes with the first pass). The shared system grows with the loops between
windows: a part's complement is dense over its shared variables, which its own ones (one chain of
poses and wheel biases) connect.
"""

from __future__ import annotations

from collections.abc import Callable

import gtsam
import numpy as np
import scipy.sparse
import scipy.sparse.linalg

from longslam.slam.graph.solver import LAMBDA_MAX, Stopping, add_damping, converged, lowered, raised

PartBuilder = Callable[[int], gtsam.NonlinearFactorGraph]


def shared_keys(build: PartBuilder, parts: int) -> set[int]:
    """The variables that factors of more than one part touch."""
    # Each part's keys once, as flat arrays (8 bytes a key, not a dict entry's 100).
    keys = np.concatenate([np.asarray(build(p).keyVector(), dtype=np.uint64) for p in range(parts)])
    unique, counts = np.unique(keys, return_counts=True)
    return {int(key) for key in unique[counts > 1]}


def _eliminate(
    graph: gtsam.NonlinearFactorGraph, values: gtsam.Values, shared: set[int], dims: dict[int, int], lam: float
) -> tuple[gtsam.GaussianBayesNet, gtsam.GaussianFactorGraph]:
    """A part linearised at `values` (damped by `lam`), its own variables eliminated: their
    conditionals on the shared ones, and the factor it leaves on those."""
    linear = graph.linearize(values)
    own = [key for key in linear.keyVector() if key not in shared]
    if lam:
        add_damping(linear, own, dims, lam)
    return linear.eliminatePartialSequential(own)


class Parts:
    """A graph given part by part, with the two passes of a step over it."""

    def __init__(self, build: PartBuilder, parts: int, dims: dict[int, int]):
        self.build, self.parts, self.dims = build, parts, dims
        self.shared = shared_keys(build, parts)

    def forward(self, values: gtsam.Values, lam: float) -> tuple[float, gtsam.GaussianFactorGraph | None]:
        """The error at `values`, and the first pass of a step from there: every part's factor
        on the shared variables (None where a part's elimination failed)."""
        error = 0.0
        on_shared: gtsam.GaussianFactorGraph | None = gtsam.GaussianFactorGraph()
        for p in range(self.parts):
            graph = self.build(p)
            error += graph.error(values)
            if on_shared is not None:
                try:
                    on_shared.push_back(_eliminate(graph, values, self.shared, self.dims, lam)[1])
                except RuntimeError:  # an indeterminate part: this step needs more damping
                    on_shared = None
        return float(error), on_shared

    def backward(self, values: gtsam.Values, on_shared: gtsam.GaussianFactorGraph, lam: float) -> gtsam.VectorValues:
        """The step: the shared variables' from the first pass's factors, then each part's own
        by back-substitution, each part linearised and eliminated again."""
        if lam:
            on_shared = on_shared.clone()
            add_damping(on_shared, list(on_shared.keyVector()), self.dims, lam)
        try:
            shared_step = on_shared.optimize()
        except RuntimeError:
            shared_step = solve_shared(on_shared, self.dims)
        whole = gtsam.VectorValues(shared_step)
        for p in range(self.parts):
            conditionals, _ = _eliminate(self.build(p), values, self.shared, self.dims, lam)
            part_step = conditionals.optimize(shared_step)
            for key in conditionals.keyVector():
                if key not in self.shared:
                    whole.insert(key, part_step.at(key))
        return whole


def solve_shared(graph: gtsam.GaussianFactorGraph, dims: dict[int, int]) -> gtsam.VectorValues:
    """The minimiser of the shared variables' system, by SciPy's sparse LU (SuperLU, pivoting),
    where GTSAM's elimination gives up on it.

    The parts' Schur complements, in information form, carry the wheels' lateral hold (1e10 per
    step) beside heading information near 1e-2, and GTSAM's Cholesky calls some such systems
    indeterminate though they are positive definite (their eigenvalues span some thirteen orders
    of magnitude, and a dense Cholesky of the same matrix succeeds)."""
    keys = list(graph.keyVector())
    offset: dict[int, int] = {}
    size = 0
    for key in keys:
        offset[key] = size
        size += dims[key]
    factors = [graph.at(i) for i in range(graph.size())]
    indices = [
        np.concatenate([np.arange(offset[k], offset[k] + dims[k], dtype=np.int32) for k in f.keys()]) for f in factors
    ]
    entries = sum(len(index) ** 2 for index in indices)
    # One preallocated triplet array (no list of per-factor copies to concatenate): it is the
    # step's largest allocation, 16 bytes an entry.
    rows, cols = np.empty(entries, dtype=np.int32), np.empty(entries, dtype=np.int32)
    values = np.empty(entries)
    rhs = np.zeros(size)
    at = 0
    for factor, index in zip(factors, indices):
        m = len(index)
        augmented = factor.augmentedInformation()
        rows[at : at + m * m] = np.repeat(index, m)
        cols[at : at + m * m] = np.tile(index, m)
        values[at : at + m * m] = augmented[:m, :m].ravel()
        np.add.at(rhs, index, augmented[:m, m])
        at += m * m
    hessian = scipy.sparse.csc_matrix((values, (rows, cols)), shape=(size, size))
    del rows, cols, values
    solution = scipy.sparse.linalg.spsolve(hessian, rhs)
    if not np.all(np.isfinite(solution)):
        raise RuntimeError("the windows' shared system is singular")
    out = gtsam.VectorValues()
    for key in keys:
        out.insert(key, solution[offset[key] : offset[key] + dims[key]])
    return out


def levenberg_marquardt_parts(
    build: PartBuilder,
    parts: int,
    values: gtsam.Values,
    dims: dict[int, int],
    stop: Stopping,
) -> tuple[gtsam.Values, int]:
    """`solver.levenberg_marquardt`'s loop (the same damping and convergence test) over a graph
    given part by part: the optimised values and the iterations taken. A candidate's error is
    found in the same pass as the first half of the next step from it, which is kept if the
    candidate is."""
    graph = Parts(build, parts, dims)
    current, on_shared = graph.forward(values, 0.0)
    lam = 0.0
    iteration = 0
    while iteration < stop.iterations:
        while True:
            next_lam = lowered(lam)
            try:
                if on_shared is None:
                    raise RuntimeError("a part is indeterminate")
                candidate = values.retract(graph.backward(values, on_shared, lam))
                on_shared = (
                    None  # not used again (a failed step redoes it more damped): freed before the next one is made
                )
                new_error, next_shared = graph.forward(candidate, next_lam)
            except RuntimeError:  # an indeterminate (or nearly so) system: damp it
                new_error = np.inf
            if new_error <= current:
                break
            if not stop.damping or lam >= LAMBDA_MAX:
                return values, iteration
            lam = raised(lam)
            _, on_shared = graph.forward(values, lam)
        iteration += 1
        decrease = current - new_error
        values, current, lam, on_shared = candidate, new_error, next_lam, next_shared
        if converged(decrease, current, stop.relative_tolerance):
            break
    return values, iteration
