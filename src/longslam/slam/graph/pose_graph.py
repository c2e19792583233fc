"""The methods' planar (x, y, yaw) pose graph: keyframe nodes, submap origins.

An edge carries a full 3x3 information matrix in the tangent space of GTSAM's `Pose2` between
factor, so a registration whose Hessian leaves a corridor's along-track direction soft stays soft;
an edge given as diagonal sigmas keeps them (and GTSAM's diagonal noise model).

The graph keeps its nodes and edges in plain Python containers and rebuilds the GTSAM factor graph
on every `optimize`: that makes removing a rejected loop closure trivial and the result a pure
function of the nodes and edges (deterministic). Each edge's GTSAM factor is made once for the
whole solves and kept with it (a local solve makes its own, see `_factor`), and whether the graph
is connected is kept up to date as edges come (a union-find, built again only after an edge is
removed): made afresh at every solve, the noise models and the search cost about as much as
the solve itself on a long route's graph.

Loop closures can be wrong (look-alike corridors). `try_loop` adds one, optimises, and rolls it
back when the optimised graph disagrees with it, in one of two ways:
- "graph": no edge of the graph may be off by more than `max_error` sigmas, translation and
  rotation judged apart (RTAB-Map's RGBD/OptimizeMaxError);
- "edge": the new edge's own Mahalanobis error must stay under `max_error` (longslam's Voxgraph).

A loop try given the nodes it may move (`free`) solves and checks only the edges that touch them,
so its cost follows the working memory's budget, not the route's length.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Collection
from dataclasses import dataclass
from typing import Literal

import gtsam
import numpy as np

from longslam.core.errors import InputError
from longslam.core.geometry import log_xyyaw, relative_xyyaw
from longslam.slam.graph import noise
from longslam.slam.graph.noise import ROBUST_KERNELS
from longslam.slam.graph.solver import gtsam_levenberg_marquardt

ODOMETRY, LOOP, REGISTRATION = "odometry", "loop", "registration"

# Sigmas of the prior that pins the first node: the graph is only defined up to a rigid motion,
# and pinning the first node keeps the optimised trajectory in the odometry's frame.
ANCHOR_SIGMAS = (1e-6, 1e-6, 1e-6)


@dataclass(frozen=True)
class Edge:
    edge_id: int
    a: int
    b: int
    delta: tuple[float, float, float]  # pose of b in a's frame
    information: np.ndarray  # (3, 3) x, y, yaw
    sigmas: tuple[float, float, float] | None  # when given as sigmas: a diagonal noise model
    kind: str  # ODOMETRY, LOOP, REGISTRATION or a caller's own
    robust: bool


@dataclass(frozen=True)
class EdgeError:
    """An edge's residual at the optimised poses, in units of its uncertainty."""

    edge_id: int
    a: int
    b: int
    kind: str
    error: float  # Mahalanobis norm of the whole (x, y, yaw) residual
    # RTAB-Map checks translation and rotation separately against OptimizeMaxError.
    translation_error: float
    rotation_error: float
    residual: tuple[float, float, float]  # unnormalised (x, y, yaw) residual


@dataclass(frozen=True)
class LoopCheck:
    """What `try_loop` decided: the edge id when kept, and the error that decided it."""

    accepted: bool
    edge_id: int | None
    error: float


def _sigmas(values, what: str) -> tuple[float, float, float]:
    arr = np.asarray(values, dtype=np.float64).reshape(-1)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise InputError(f"{what}: sigmas must be three positive finite numbers (x, y, yaw), got {values!r}")
    return float(arr[0]), float(arr[1]), float(arr[2])


def _information(values, what: str) -> np.ndarray:
    info = np.asarray(values, dtype=np.float64)
    if info.shape != (3, 3) or not np.all(np.isfinite(info)):
        raise InputError(f"{what}: information must be a finite 3x3 matrix, got shape {info.shape}")
    info = 0.5 * (info + info.T)
    if np.linalg.eigvalsh(info)[0] <= 0:
        raise InputError(f"{what}: information must be positive definite")
    return info


def _xyyaw(values, what: str) -> tuple[float, float, float]:
    arr = np.asarray(values, dtype=np.float64).reshape(-1)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise InputError(f"{what}: expected three finite numbers (x, y, yaw), got {values!r}")
    return float(arr[0]), float(arr[1]), float(arr[2])


class PoseGraph:
    """Nodes with (x, y, yaw) estimates; edges with full information, optionally robust."""

    def __init__(self, robust_kernel: str = "cauchy", robust_k: float = 1.0, max_iterations: int = 100):
        if robust_kernel not in ROBUST_KERNELS:
            raise InputError(f"robust_kernel must be one of {', '.join(ROBUST_KERNELS)}, got {robust_kernel!r}")
        # Cauchy by default: its influence falls off for large residuals, so a grossly wrong
        # closure hardly bends the graph; Huber still pulls with a constant force.
        self.robust_kernel = robust_kernel
        self.robust_k = float(robust_k)
        self.max_iterations = int(max_iterations)
        self._initial: dict[int, tuple[float, float, float]] = {}
        self._edges: dict[int, Edge] = {}
        self._next_edge = 0
        self._optimized: dict[int, tuple[float, float, float]] = {}
        self.last_error: float | None = None  # total graph error after the last whole solve
        self.last_iterations: int = 0
        self.optimizations = 0  # optimisations actually run
        self._order_of: dict[int, int] = {}  # node id -> its place in the adding order
        self._factors: dict[int, gtsam.BetweenFactorPose2] = {}  # edge id -> its factor, made at its first solve
        self._touching: dict[int, set[int]] = {}  # node id -> the ids of the edges at it (a local solve's edges)
        self._components: _Components | None = _Components()  # None: rebuilt at the next check (an edge was removed)

    # --- building

    def add_node(self, node_id: int, xyyaw) -> None:
        """Add a node, or replace the initial estimate of an existing one."""
        node_id = int(node_id)
        self._order_of.setdefault(node_id, len(self._order_of))
        self._initial[node_id] = _xyyaw(xyyaw, f"node {node_id}")
        if self._components is not None:
            self._components.add(node_id)

    def has_node(self, node_id: int) -> bool:
        return int(node_id) in self._initial

    def add_edge(
        self, a: int, b: int, delta, *, sigmas=None, information=None, kind: str = ODOMETRY, robust: bool = False
    ) -> int:
        """Add a constraint: the pose of b in a's frame, with `sigmas` (x, y, yaw) or a 3x3
        `information` matrix (exactly one of them). Returns the edge id."""
        a, b = int(a), int(b)
        what = f"{kind} edge {a}->{b}"
        for node in (a, b):
            if node not in self._initial:
                raise InputError(f"{what}: node {node} has not been added")
        if a == b:
            raise InputError(f"{what}: an edge must join two different nodes")
        if (sigmas is None) == (information is None):
            raise InputError(f"{what}: give either sigmas or an information matrix")
        if sigmas is not None:
            sig = _sigmas(sigmas, what)
            info = np.diag(1.0 / np.square(sig))
        else:
            sig, info = None, _information(information, what)
        edge_id = self._next_edge
        self._next_edge += 1
        self._edges[edge_id] = Edge(edge_id, a, b, _xyyaw(delta, what), info, sig, kind, bool(robust))
        if self._components is not None:
            self._components.join(a, b)
        self._touching.setdefault(a, set()).add(edge_id)
        self._touching.setdefault(b, set()).add(edge_id)
        return edge_id

    def add_odometry(self, a: int, b: int, delta_xyyaw, sigmas=None, information=None) -> int:
        return self.add_edge(a, b, delta_xyyaw, sigmas=sigmas, information=information, kind=ODOMETRY)

    def add_loop(self, a: int, b: int, delta_xyyaw, sigmas=None, information=None, robust: bool = True) -> int:
        """Add a loop-closure constraint (pose of b in a's frame); returns its edge id.

        A robust kernel judges the residual against this edge's own uncertainty. After a long
        drift a *correct* closure can sit tens of sigmas away from the odometry estimate and be
        muted as well, so for closures that must pull a drifted graph back either give sigmas that
        include the drift, or use `try_loop` (robust=False, rejected afterwards by its error).
        """
        return self.add_edge(a, b, delta_xyyaw, sigmas=sigmas, information=information, kind=LOOP, robust=robust)

    def remove_edge(self, edge_id: int) -> None:
        if edge_id not in self._edges:
            raise InputError(f"no edge with id {edge_id}")
        edge = self._edges.pop(edge_id)
        self._touching[edge.a].discard(edge_id)
        self._touching[edge.b].discard(edge_id)
        self._factors.pop(edge_id, None)
        self._components = None  # the edge may have held two parts together

    def try_loop(
        self,
        a: int,
        b: int,
        delta_xyyaw,
        *,
        max_error: float,
        sigmas=None,
        information=None,
        check: Literal["graph", "edge"] = "graph",
        kind: str = LOOP,
        free: Collection[int] | None = None,
    ) -> LoopCheck:
        """Add a closure, optimise (warm), and keep it only if the graph agrees; else remove it and
        re-optimise, so a rejected closure leaves the estimates as they were before it.

        With `free` (node ids), only those nodes move: the solve and the "graph" check take the
        edges that touch them, with the nodes at those edges' other ends held where they are
        (`optimize_local`). That is RTAB-Map's optimisation of the map in working memory: its cost
        is bounded by the memory's budget, not the route's length."""
        edge_id = self.add_edge(a, b, delta_xyyaw, sigmas=sigmas, information=information, kind=kind, robust=False)
        if check not in ("graph", "edge"):
            self.remove_edge(edge_id)
            raise InputError(f"try_loop: check must be 'graph' or 'edge', got {check!r}")
        if free is not None:
            return self._try_loop_local(edge_id, set(map(int, free)) | {int(a), int(b)}, max_error, check)
        self._solve(warm_start=True)
        if check == "edge":
            error = self.edge_error(edge_id)
        else:
            error = max(max(e.translation_error, e.rotation_error) for e in self.edge_errors(None))
        if error > max_error:
            self.remove_edge(edge_id)
            self._solve(warm_start=True)
            return LoopCheck(False, None, float(error))
        return LoopCheck(True, edge_id, float(error))

    def _try_loop_local(self, edge_id: int, free: set[int], max_error: float, check: str) -> LoopCheck:
        before = {n: self._optimized.get(n) for n in free}
        edges = self.optimize_local(free)
        if check == "edge":
            error = self.edge_error(edge_id)
        else:
            # One numpy pass: edge by edge in Python, the check cost more than the solve.
            error = _max_split_error(
                np.array([e.delta for e in edges]),
                np.array([e.information for e in edges]),
                self.estimates([e.a for e in edges]),
                self.estimates([e.b for e in edges]),
            )
        if error > max_error:
            self.remove_edge(edge_id)
            # The free nodes go back to where they were: the rest never moved.
            for node, pose in before.items():
                if pose is None:
                    self._optimized.pop(node, None)
                else:
                    self._optimized[node] = pose
            return LoopCheck(False, None, float(error))
        return LoopCheck(True, edge_id, float(error))

    def optimize_local(self, free: Collection[int], max_iterations: int | None = None) -> list[Edge]:
        """Optimise the `free` nodes alone, warm: every edge that touches one of them, with the
        nodes at their other ends held at their estimates (where no such node holds a connected
        group of free nodes, its first node is held). Returns the edges solved. Whole-graph
        solves (`optimize`) are left as they are: a free set that holds every node gives the same
        problem as a warm whole solve, but anchored at the first node's estimate."""
        free = {int(n) for n in free if int(n) in self._initial}
        # In the order they were added (edge ids grow), as a scan of every edge would give them.
        touching = self._touching
        edges = [self._edges[i] for i in sorted({i for n in free for i in touching.get(n, ())})]
        if not edges:
            return []
        touched = sorted({n for e in edges for n in (e.a, e.b)}, key=self._order)
        held = {n for n in touched if n not in free}
        # A group of free nodes no held node reaches would float: hold its first node.
        parent = {n: n for n in touched}

        def root(n: int) -> int:
            while parent[n] != n:
                parent[n] = parent[parent[n]]
                n = parent[n]
            return n

        for e in edges:
            ra, rb = root(e.a), root(e.b)
            if ra != rb:
                parent[max(ra, rb, key=self._order)] = min(ra, rb, key=self._order)
        anchored = {root(n) for n in held}
        for n in touched:  # in order: the first node of each group
            if root(n) not in anchored:
                anchored.add(root(n))
                held.add(n)
        graph = gtsam.NonlinearFactorGraph()
        values = gtsam.Values()
        for n in touched:
            start = gtsam.Pose2(*self.estimate(n))
            values.insert(n, start)
            if n in held:
                graph.add(gtsam.PriorFactorPose2(n, start, noise.diagonal(ANCHOR_SIGMAS)))
        for e in edges:
            graph.add(self._factor(e, keep=False))
        result, self.last_iterations = gtsam_levenberg_marquardt(
            graph, values, self.max_iterations if max_iterations is None else max_iterations
        )
        self.optimizations += 1
        for n in touched:
            if n not in held:
                p = result.atPose2(n)
                self._optimized[n] = (float(p.x()), float(p.y()), float(p.theta()))
        return edges

    def _order(self, node_id: int) -> int:
        """A node's place in the order nodes were added (node ids need not be sorted)."""
        return self._order_of[node_id]

    # --- inspecting

    @property
    def nodes(self) -> list[int]:
        return list(self._initial)

    @property
    def edges(self) -> list[Edge]:
        return list(self._edges.values())

    @property
    def num_nodes(self) -> int:
        return len(self._initial)

    def count(self, kind: str) -> int:
        return sum(e.kind == kind for e in self._edges.values())

    @property
    def num_odometry(self) -> int:
        return self.count(ODOMETRY)

    @property
    def num_loops(self) -> int:
        return self.count(LOOP)

    def counts(self) -> dict[str, int]:
        return {"nodes": self.num_nodes, "odometry_edges": self.num_odometry, "loop_edges": self.num_loops}

    def estimate(self, node_id: int) -> np.ndarray:
        """Latest optimised pose (x, y, yaw) of a node, or its initial estimate if not optimised yet."""
        node_id = int(node_id)
        return np.array(self._optimized.get(node_id, self._initial[node_id]))

    def estimates(self, node_ids) -> np.ndarray:
        """`estimate` of many nodes at once, (N, 3) x, y, yaw."""
        ids = [int(n) for n in node_ids]
        optimized, initial = self._optimized, self._initial
        return np.array([optimized.get(n) or initial[n] for n in ids], dtype=np.float64).reshape(len(ids), 3)

    # --- optimising

    def _noise(self, edge: Edge) -> gtsam.noiseModel.Base:
        base = noise.diagonal(edge.sigmas) if edge.sigmas is not None else noise.gaussian(edge.information)
        return noise.robust(base, self.robust_kernel, self.robust_k) if edge.robust else base

    def _factor(self, edge: Edge, keep: bool = True) -> gtsam.BetweenFactorPose2:
        """The edge's factor, kept for the next solve if `keep`. A local solve does not keep what
        it makes: its edges move on with working memory, and keeping every edge it ever touched
        (about 750 bytes an edge) would grow with the route."""
        factor = self._factors.get(edge.edge_id)
        if factor is None:
            factor = _between_factor(edge, self._noise(edge))
            if keep:
                self._factors[edge.edge_id] = factor
        return factor

    def _check_connected(self) -> None:
        # An island of nodes not linked to the anchored first node makes the system singular
        # and GTSAM fails with an opaque indeterminant-system error; name the culprit instead.
        if self._components is None:
            self._components = _Components()
            for node in self._initial:
                self._components.add(node)
            for e in self._edges.values():
                self._components.join(e.a, e.b)
        if self._components.count <= 1:
            return
        adjacency: dict[int, list[int]] = {n: [] for n in self._initial}
        for e in self._edges.values():
            adjacency[e.a].append(e.b)
            adjacency[e.b].append(e.a)
        first = next(iter(self._initial))
        seen = {first}
        queue = deque([first])
        while queue:
            for nxt in adjacency[queue.popleft()]:
                if nxt not in seen:
                    seen.add(nxt)
                    queue.append(nxt)
        if len(seen) != len(self._initial):
            missing = sorted(set(self._initial) - seen)
            raise InputError(
                f"pose graph is not connected: {len(missing)} node(s) have no path to the first node "
                f"{first} (e.g. {missing[:5]})"
            )

    def optimize(
        self, max_iterations: int | None = None, warm_start: bool = False
    ) -> dict[int, tuple[float, float, float]]:
        """Optimise all nodes, the first added node fixed; returns {node_id: (x, y, yaw)}.

        By default the optimisation starts from the nodes' initial estimates, so the result
        depends only on the graph's contents (removing an edge and re-optimising restores the
        earlier result). `warm_start` starts from the last optimised poses instead, which
        converges faster when a long graph grows by a few nodes at a time. A graph without
        edges has nothing to optimise: its estimates stay as they are.
        """
        self._solve(max_iterations, warm_start)
        if self._optimized:
            return dict(self._optimized)
        return {n: tuple(self.estimate(n)) for n in self._initial}

    def _solve(self, max_iterations: int | None = None, warm_start: bool = False) -> None:
        if not self._edges:
            return
        self._check_connected()
        graph = gtsam.NonlinearFactorGraph()
        first = next(iter(self._initial))
        graph.add(gtsam.PriorFactorPose2(first, gtsam.Pose2(*self._initial[first]), noise.diagonal(ANCHOR_SIGMAS)))
        for e in self._edges.values():
            graph.add(self._factor(e))
        values = gtsam.Values()
        for node, xyyaw in self._initial.items():
            start = self._optimized.get(node, xyyaw) if warm_start else xyyaw
            values.insert(node, gtsam.Pose2(*start))
        result, self.last_iterations = gtsam_levenberg_marquardt(
            graph, values, self.max_iterations if max_iterations is None else max_iterations
        )
        self.last_error = float(graph.error(result))
        self.optimizations += 1
        out: dict[int, tuple[float, float, float]] = {}
        for node in self._initial:
            p = result.atPose2(node)
            out[node] = (float(p.x()), float(p.y()), float(p.theta()))
        self._optimized = out

    def _residual(self, e: Edge) -> np.ndarray:
        pa, pb = gtsam.Pose2(*self.estimate(e.a)), gtsam.Pose2(*self.estimate(e.b))
        return np.asarray(gtsam.Pose2(*e.delta).localCoordinates(pa.between(pb)), dtype=np.float64)

    def edge_error(self, edge_id: int) -> float:
        """Mahalanobis norm of an edge's residual at the latest estimates."""
        e = self._edges[edge_id]
        r = self._residual(e)
        return float(np.sqrt(max(r @ e.information @ r, 0.0)))

    def edge_errors(self, kind: str | None = LOOP) -> list[EdgeError]:
        """Each edge's residual at the latest poses, in units of its uncertainty.

        `kind` selects one kind of edge (LOOP by default), or None for all. The error is the plain
        (not robust-weighted) Mahalanobis norm, so a closure the robust kernel has muted still
        shows how badly it disagrees with the rest of the graph. Translation and rotation errors
        use the translation block and the yaw entry of the information (for sigmas: r / sigma).
        """
        return self._edge_errors(e for e in self._edges.values() if kind is None or e.kind == kind)

    def _edge_errors(self, edges) -> list[EdgeError]:
        out = []
        for e in edges:
            residual = self._residual(e)
            if e.sigmas is not None:
                norm = residual / np.asarray(e.sigmas)
                error = float(np.linalg.norm(norm))
                translation = float(np.linalg.norm(norm[:2]))
                rotation = float(abs(norm[2]))
            else:
                info = e.information
                error = float(np.sqrt(max(residual @ info @ residual, 0.0)))
                translation = float(np.sqrt(max(residual[:2] @ info[:2, :2] @ residual[:2], 0.0)))
                rotation = float(abs(residual[2]) * np.sqrt(info[2, 2]))
            out.append(
                EdgeError(
                    e.edge_id,
                    e.a,
                    e.b,
                    e.kind,
                    error=error,
                    translation_error=translation,
                    rotation_error=rotation,
                    residual=(float(residual[0]), float(residual[1]), float(residual[2])),
                )
            )
        return out

    def max_edge_error(self, kind: str | None = LOOP) -> EdgeError | None:
        """The edge with the largest normalised error (None if there are no such edges)."""
        errors = self.edge_errors(kind)
        return max(errors, key=lambda e: e.error) if errors else None


def _between_factor(edge: Edge, noise_model: gtsam.noiseModel.Base) -> gtsam.BetweenFactorPose2:
    return gtsam.BetweenFactorPose2(edge.a, edge.b, gtsam.Pose2(*edge.delta), noise_model)


class _Components:
    """Union-find over the nodes: how many connected parts the edges added so far leave."""

    def __init__(self) -> None:
        self.parent: dict[int, int] = {}
        self.count = 0

    def add(self, node: int) -> None:
        if node not in self.parent:
            self.parent[node] = node
            self.count += 1

    def _root(self, node: int) -> int:
        parent = self.parent
        while parent[node] != node:
            parent[node] = parent[parent[node]]
            node = parent[node]
        return node

    def join(self, a: int, b: int) -> None:
        ra, rb = self._root(a), self._root(b)
        if ra != rb:
            self.parent[rb] = ra
            self.count -= 1


def _max_split_error(delta: np.ndarray, information: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """The largest translation or rotation error of edges (N, 3) `delta` with (N, 3, 3)
    `information` between poses `a` and `b` (N, 3), each judged in its own sigmas as
    `PoseGraph.edge_errors` does, in one numpy pass."""
    residual = log_xyyaw(relative_xyyaw(delta, relative_xyyaw(a, b)))
    translation = np.sqrt(
        np.maximum(np.einsum("ni,nij,nj->n", residual[:, :2], information[:, :2, :2], residual[:, :2]), 0.0)
    )
    rotation = np.abs(residual[:, 2]) * np.sqrt(information[:, 2, 2])
    return float(max(translation.max(), rotation.max()))
