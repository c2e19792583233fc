"""The submap pose graph: planar (x, y, yaw) submap origins on GTSAM, with full-information edges.

Registration constraints carry a full 3x3 information matrix (the Gauss-Newton Hessian of the
registration), so a corridor's unobservable along-track direction stays soft; that is why this
graph does not use `PoseGraph2D`, whose edges have diagonal sigmas. Nodes are the submaps'
origins on the floor: z is the floor's height for every node (a planar robot), roll and pitch are
zero, so (x, y, yaw) are the only free coordinates of Voxgraph's (x, y, z, yaw).
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np

ODOMETRY, REGISTRATION, LOOP = "odometry", "registration", "loop"
_ANCHOR = gtsam.noiseModel.Diagonal.Sigmas(np.array([1e-6, 1e-6, 1e-6]))


@dataclass(frozen=True)
class GraphEdge:
    a: int
    b: int
    delta: np.ndarray  # (3,) pose of b in a's frame
    information: np.ndarray  # (3, 3), in the tangent space of GTSAM's Pose2 between factor
    kind: str
    robust: bool


class SubmapGraph:
    def __init__(self, robust_kernel: str = "cauchy", robust_k: float = 2.0):
        self.robust_kernel = robust_kernel
        self.robust_k = float(robust_k)
        self._estimate: dict[int, np.ndarray] = {}
        self._edges: dict[int, GraphEdge] = {}
        self._next = 0
        self.optimisations = 0

    @property
    def nodes(self) -> list[int]:
        return list(self._estimate)

    @property
    def edges(self) -> list[GraphEdge]:
        return list(self._edges.values())

    def count(self, kind: str) -> int:
        return sum(e.kind == kind for e in self._edges.values())

    def add_node(self, node: int, xyyaw) -> None:
        self._estimate[int(node)] = np.asarray(xyyaw, dtype=np.float64).reshape(3).copy()

    def estimate(self, node: int) -> np.ndarray:
        return self._estimate[int(node)].copy()

    def add_edge(self, a: int, b: int, delta, information, kind: str, robust: bool = False) -> int:
        edge_id = self._next
        self._next += 1
        info = np.asarray(information, dtype=np.float64).reshape(3, 3)
        self._edges[edge_id] = GraphEdge(int(a), int(b), np.asarray(delta, dtype=np.float64).reshape(3).copy(), info, kind, robust)
        return edge_id

    def remove_edge(self, edge_id: int) -> None:
        del self._edges[edge_id]

    def _noise(self, edge: GraphEdge):
        base = gtsam.noiseModel.Gaussian.Information(edge.information)
        if not edge.robust or self.robust_kernel == "none":
            return base
        if self.robust_kernel == "cauchy":
            kernel = gtsam.noiseModel.mEstimator.Cauchy.Create(self.robust_k)
        else:
            kernel = gtsam.noiseModel.mEstimator.Huber.Create(self.robust_k)
        return gtsam.noiseModel.Robust.Create(kernel, base)

    def optimize(self, max_iterations: int = 50) -> None:
        """Optimise every node from the current estimates, the first node fixed."""
        if len(self._estimate) < 2 or not self._edges:
            return
        graph = gtsam.NonlinearFactorGraph()
        first = next(iter(self._estimate))
        graph.add(gtsam.PriorFactorPose2(first, gtsam.Pose2(*self._estimate[first]), _ANCHOR))
        for e in self._edges.values():
            graph.add(gtsam.BetweenFactorPose2(e.a, e.b, gtsam.Pose2(*e.delta), self._noise(e)))
        values = gtsam.Values()
        for node, xyyaw in self._estimate.items():
            values.insert(node, gtsam.Pose2(*xyyaw))
        params = gtsam.LevenbergMarquardtParams()
        params.setMaxIterations(int(max_iterations))
        result = gtsam.LevenbergMarquardtOptimizer(graph, values, params).optimize()
        for node in self._estimate:
            p = result.atPose2(node)
            self._estimate[node] = np.array([p.x(), p.y(), p.theta()])
        self.optimisations += 1

    def edge_error(self, edge_id: int) -> float:
        """Mahalanobis norm of an edge's residual at the current estimates."""
        e = self._edges[edge_id]
        pa, pb = gtsam.Pose2(*self._estimate[e.a]), gtsam.Pose2(*self._estimate[e.b])
        r = np.asarray(gtsam.Pose2(*e.delta).localCoordinates(pa.between(pb)), dtype=np.float64)
        return float(np.sqrt(max(r @ e.information @ r, 0.0)))
