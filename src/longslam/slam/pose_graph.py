"""A planar (x, y, yaw) pose graph optimised with GTSAM, shared by the keyframe and submap methods.

The graph keeps its nodes and edges in plain Python containers and rebuilds the GTSAM factor
graph on every `optimize`: that makes removing a rejected loop closure trivial and the result a
pure function of the nodes and edges (deterministic), at a cost that is small next to the
optimisation itself.

Loop closures can be wrong (look-alike corridors), so they get a robust kernel by default and,
after optimisation, `edge_errors` reports each edge's error normalised by its sigmas, so a caller
can reject the newest closure the way RTAB-Map does with RGBD/OptimizeMaxError (3.0).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import gtsam
import numpy as np

from longslam.errors import InputError
from longslam.geometry import planar_pose, wrap_angle

ODOMETRY, LOOP = "odometry", "loop"

# Sigmas of the prior that pins the first node: the graph is only defined up to a rigid motion,
# and pinning the first node keeps the optimised trajectory in the odometry's frame.
ANCHOR_SIGMAS = (1e-6, 1e-6, 1e-6)


# ----------------------------------------------------------------------------- planar helpers

def xyyaw_from_pose(pose: np.ndarray) -> np.ndarray:
    """(4, 4) or (N, 4, 4) planar pose(s) -> (3,) or (N, 3) x, y, yaw.

    Only the rotation about z is kept; for camera poses use
    `geometry.planar_from_camera_poses`, which first removes the camera's mounting rotation.
    """
    pose = np.asarray(pose, dtype=np.float64)
    yaw = np.arctan2(pose[..., 1, 0], pose[..., 0, 0])
    return np.stack([pose[..., 0, 3], pose[..., 1, 3], yaw], axis=-1)


def pose_from_xyyaw(xyyaw: np.ndarray, z: float = 0.0) -> np.ndarray:
    """(3,) x, y, yaw -> (4, 4) pose (see `geometry.planar_poses` for many at once)."""
    x, y, yaw = (float(v) for v in np.asarray(xyyaw, dtype=np.float64).reshape(3))
    return planar_pose(x, y, yaw, z)


def relative_xyyaw(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Pose of b expressed in a's frame (a^-1 * b); works on (3,) or broadcast (N, 3) arrays."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    dx, dy = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack([c * dx + s * dy, -s * dx + c * dy, wrap_angle(b[..., 2] - a[..., 2])], axis=-1)


def compose_xyyaw(a: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """a * delta: the pose reached by moving `delta` (in a's frame) from a."""
    a = np.asarray(a, dtype=np.float64)
    delta = np.asarray(delta, dtype=np.float64)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = a[..., 0] + c * delta[..., 0] - s * delta[..., 1]
    y = a[..., 1] + s * delta[..., 0] + c * delta[..., 1]
    return np.stack([x, y, wrap_angle(a[..., 2] + delta[..., 2])], axis=-1)


# ----------------------------------------------------------------------------- the graph

@dataclass(frozen=True)
class Edge:
    edge_id: int
    a: int
    b: int
    delta: tuple[float, float, float]  # pose of b in a's frame
    sigmas: tuple[float, float, float]  # x, y (m), yaw (rad)
    kind: str  # ODOMETRY or LOOP
    robust: bool


@dataclass(frozen=True)
class EdgeError:
    """An edge's residual at the optimised poses, in units of its sigmas."""

    edge_id: int
    a: int
    b: int
    kind: str
    error: float  # Mahalanobis norm of the whole (x, y, yaw) residual
    # RTAB-Map checks translation and rotation separately against OptimizeMaxError.
    translation_error: float
    rotation_error: float
    residual: tuple[float, float, float]  # unnormalised (x, y, yaw) residual


def _sigmas(values, what: str) -> tuple[float, float, float]:
    arr = np.asarray(values, dtype=np.float64).reshape(-1)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise InputError(f"{what}: sigmas must be three positive finite numbers (x, y, yaw), got {values!r}")
    return tuple(float(v) for v in arr)


def _xyyaw(values, what: str) -> tuple[float, float, float]:
    arr = np.asarray(values, dtype=np.float64).reshape(-1)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise InputError(f"{what}: expected three finite numbers (x, y, yaw), got {values!r}")
    return float(arr[0]), float(arr[1]), float(arr[2])


class PoseGraph2D:
    """Nodes with (x, y, yaw) estimates, odometry edges and (robust) loop-closure edges."""

    def __init__(self, robust_kernel: str = "cauchy", robust_k: float = 1.0):
        if robust_kernel not in ("cauchy", "huber"):
            raise InputError(f"robust_kernel must be 'cauchy' or 'huber', got {robust_kernel!r}")
        # Cauchy by default: its influence falls off for large residuals, so a grossly wrong
        # closure hardly bends the graph; Huber still pulls with a constant force.
        self.robust_kernel = robust_kernel
        self.robust_k = float(robust_k)
        self._initial: dict[int, tuple[float, float, float]] = {}
        self._edges: dict[int, Edge] = {}
        self._next_edge = 0
        self._optimized: dict[int, tuple[float, float, float]] = {}
        self.last_error: float | None = None  # total graph error after the last optimize
        self.last_iterations: int = 0

    # --- building

    def add_node(self, node_id: int, xyyaw) -> None:
        """Add a node, or replace the initial estimate of an existing one."""
        self._initial[int(node_id)] = _xyyaw(xyyaw, f"node {node_id}")

    def has_node(self, node_id: int) -> bool:
        return int(node_id) in self._initial

    def add_odometry(self, a: int, b: int, delta_xyyaw, sigmas) -> int:
        return self._add_edge(a, b, delta_xyyaw, sigmas, ODOMETRY, robust=False)

    def add_loop(self, a: int, b: int, delta_xyyaw, sigmas, robust: bool = True) -> int:
        """Add a loop-closure constraint (pose of b in a's frame); returns its edge id.

        A robust kernel judges the residual against this edge's own sigmas. After a long drift
        a *correct* closure can sit tens of sigmas away from the odometry estimate and be muted
        as well, so for closures that must pull a drifted graph back either give sigmas that
        include the drift, or pass robust=False and reject bad closures afterwards with
        `edge_errors` (RTAB-Map's RGBD/OptimizeMaxError way).
        """
        return self._add_edge(a, b, delta_xyyaw, sigmas, LOOP, robust=robust)

    def _add_edge(self, a: int, b: int, delta, sigmas, kind: str, robust: bool) -> int:
        a, b = int(a), int(b)
        for node in (a, b):
            if node not in self._initial:
                raise InputError(f"{kind} edge {a}->{b}: node {node} has not been added")
        if a == b:
            raise InputError(f"{kind} edge {a}->{b}: an edge must join two different nodes")
        edge_id = self._next_edge
        self._next_edge += 1
        self._edges[edge_id] = Edge(
            edge_id, a, b, _xyyaw(delta, f"{kind} edge {a}->{b}"), _sigmas(sigmas, f"{kind} edge {a}->{b}"),
            kind, bool(robust),
        )
        return edge_id

    def remove_edge(self, edge_id: int) -> None:
        if edge_id not in self._edges:
            raise InputError(f"no edge with id {edge_id}")
        del self._edges[edge_id]

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

    @property
    def num_odometry(self) -> int:
        return sum(e.kind == ODOMETRY for e in self._edges.values())

    @property
    def num_loops(self) -> int:
        return sum(e.kind == LOOP for e in self._edges.values())

    def counts(self) -> dict[str, int]:
        return {"nodes": self.num_nodes, "odometry_edges": self.num_odometry, "loop_edges": self.num_loops}

    def estimate(self, node_id: int) -> tuple[float, float, float]:
        """Latest optimised pose of a node, or its initial estimate if not optimised yet."""
        node_id = int(node_id)
        return self._optimized.get(node_id, self._initial[node_id])

    # --- optimising

    def _noise(self, edge: Edge):
        base = gtsam.noiseModel.Diagonal.Sigmas(np.asarray(edge.sigmas))
        if not edge.robust:
            return base
        if self.robust_kernel == "cauchy":
            kernel = gtsam.noiseModel.mEstimator.Cauchy.Create(self.robust_k)
        else:
            kernel = gtsam.noiseModel.mEstimator.Huber.Create(self.robust_k)
        return gtsam.noiseModel.Robust.Create(kernel, base)

    def _check_connected(self) -> None:
        # An island of nodes not linked to the anchored first node makes the system singular
        # and GTSAM fails with an opaque indeterminant-system error; name the culprit instead.
        if not self._initial:
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

    def optimize(self, max_iterations: int = 100, warm_start: bool = False) -> dict[int, tuple[float, float, float]]:
        """Optimise all nodes, the first added node fixed; returns {node_id: (x, y, yaw)}.

        By default the optimisation starts from the nodes' initial estimates, so the result
        depends only on the graph's contents (removing an edge and re-optimising restores the
        earlier result). `warm_start` starts from the last optimised poses instead, which
        converges faster when a long graph grows by a few nodes at a time.
        """
        if not self._initial:
            self._optimized = {}
            return {}
        self._check_connected()
        graph = gtsam.NonlinearFactorGraph()
        first = next(iter(self._initial))
        graph.add(gtsam.PriorFactorPose2(
            first, gtsam.Pose2(*self._initial[first]), gtsam.noiseModel.Diagonal.Sigmas(np.asarray(ANCHOR_SIGMAS))
        ))
        for e in self._edges.values():
            graph.add(gtsam.BetweenFactorPose2(e.a, e.b, gtsam.Pose2(*e.delta), self._noise(e)))
        values = gtsam.Values()
        for node, xyyaw in self._initial.items():
            start = self._optimized.get(node, xyyaw) if warm_start else xyyaw
            values.insert(node, gtsam.Pose2(*start))
        params = gtsam.LevenbergMarquardtParams()
        params.setMaxIterations(int(max_iterations))
        optimizer = gtsam.LevenbergMarquardtOptimizer(graph, values, params)
        result = optimizer.optimize()
        self.last_error = float(graph.error(result))
        self.last_iterations = int(optimizer.iterations())
        out: dict[int, tuple[float, float, float]] = {}
        for node in self._initial:
            p = result.atPose2(node)
            out[node] = (float(p.x()), float(p.y()), float(p.theta()))
        self._optimized = out
        return dict(out)

    def edge_errors(self, kind: str | None = LOOP) -> list[EdgeError]:
        """Each edge's residual at the latest poses, normalised by its sigmas.

        `kind` selects LOOP (default) or ODOMETRY edges, or None for all. The error is the plain
        (not robust-weighted) Mahalanobis norm, so a closure the robust kernel has muted still
        shows how badly it disagrees with the rest of the graph.
        """
        out = []
        for e in self._edges.values():
            if kind is not None and e.kind != kind:
                continue
            pa, pb = gtsam.Pose2(*self.estimate(e.a)), gtsam.Pose2(*self.estimate(e.b))
            residual = np.asarray(gtsam.Pose2(*e.delta).localCoordinates(pa.between(pb)), dtype=np.float64)
            sig = np.asarray(e.sigmas)
            norm = residual / sig
            out.append(EdgeError(
                e.edge_id, e.a, e.b, e.kind,
                error=float(np.linalg.norm(norm)),
                translation_error=float(np.linalg.norm(norm[:2])),
                rotation_error=float(abs(norm[2])),
                residual=(float(residual[0]), float(residual[1]), float(residual[2])),
            ))
        return out

    def max_edge_error(self, kind: str | None = LOOP) -> EdgeError | None:
        """The edge with the largest normalised error (None if there are no such edges)."""
        errors = self.edge_errors(kind)
        return max(errors, key=lambda e: e.error) if errors else None
