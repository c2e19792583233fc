"""Loop closure for the keyframe method: hypotheses, verification, and the graph's verdict.

Hypotheses come from the visual vocabulary (tf-idf over working memory, Kp/ and Rtabmap/
LoopThr) and from proximity to the current estimate (RGBD/ProximityBySpace). Each is verified
by PnP RANSAC (Vis/MinInliers), polished on 3D-3D matches (Vis/EstimationType 0), must be planar,
and is kept only if the optimised graph agrees with it (RGBD/OptimizeMaxError).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from longslam.core.frame import Intrinsics
from longslam.core.geometry import pose_from_xyyaw, wrap_angle
from longslam.slam.features import Features
from longslam.slam.graph import LoopCheck, PoseGraph
from longslam.slam.keyframe.config import KeyframeConfig
from longslam.slam.keyframe.memory import KeyframeMemory, Node
from longslam.slam.keyframe.scan_proximity import ScanLinkSettings, scan_link
from longslam.slam.place_recognition import depth_held_transform, noisy_link_sigmas, planar_link, verify

APPEARANCE, PROXIMITY, SCAN = "appearance", "proximity", "scan_proximity"
SOURCES = (APPEARANCE, PROXIMITY, SCAN)
# Visual links PnP verified but both images' depth did not hold (`loop_min_depth_support`); each is
# also counted in its source's rejected_verification.
UNHELD_BY_DEPTH = "visual_rejected_depth"


def counter_names() -> list[str]:
    """The per-source counters this module keeps (hypotheses, accepted, rejected and why)."""
    return [
        f"{s}_{what}" for s in SOURCES for what in ("hypotheses", "accepted", "rejected_verification", "rejected_graph")
    ] + [f"{SCAN}_one_direction", UNHELD_BY_DEPTH]


class NodePositions:
    """Every node's id, stamp and estimate as arrays, for the spatial searches: built from the
    graph node by node at each search, a route's thousands of nodes cost more than the search."""

    def __init__(self) -> None:
        self.ids = np.zeros(0, np.int64)
        self.stamps = np.zeros(0)
        self.estimates = np.zeros((0, 3))
        self._rows: dict[int, int] = {}

    def sync(self, nodes: dict[int, Node], graph: PoseGraph) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The arrays, with the nodes added since the last call (`nodes` in the order they were made)."""
        if len(nodes) > len(self.ids):
            new = list(nodes)[len(self.ids) :]
            for i in new:
                self._rows[i] = len(self._rows)
            self.ids = np.concatenate([self.ids, np.array(new, np.int64)])
            self.stamps = np.concatenate([self.stamps, [nodes[i].stamp for i in new]])
            self.estimates = np.concatenate([self.estimates, np.array([graph.estimate(i) for i in new]).reshape(-1, 3)])
        return self.ids, self.stamps, self.estimates

    def refresh(self, graph: PoseGraph, ids: set[int] | None) -> None:
        """Take the graph's estimates of `ids` (None: every node) after it moved them."""
        for i in self._rows if ids is None else ids:
            row = self._rows.get(i)
            if row is not None:
                self.estimates[row] = graph.estimate(i)


@dataclass
class LoopCloser:
    config: KeyframeConfig
    intrinsics: Intrinsics
    graph: PoseGraph  # the keyframe graph, whose verdict keeps or drops a closure
    memory: KeyframeMemory  # whose working memory is searched and whose database keeps the links
    camera_in_base: np.ndarray  # (4, 4)
    counts: dict[str, int]  # the method's counters, which this updates
    positions: NodePositions = field(default_factory=NodePositions)
    depth_noise: float | None = None  # the current node's inverse-depth noise (1/m; None: exact)
    min_inliers: int | None = None  # the current node's PnP inliers (MethodDepths.loop_min_inliers; None: the config's)

    def detect(self, node: Node, words: np.ndarray) -> None:
        """Try the new node against working memory: the best appearance hypotheses (one loop at
        most: the graph is re-optimised for each), then the nearby nodes not tried yet."""
        cfg = self.config
        searchable = self.memory.searchable()
        tried: set[int] = set()
        if searchable:
            for cand, score in self.memory.vocabulary.query_words(words, searchable, top_k=cfg.loop_candidates):
                if score < cfg.loop_threshold:
                    break
                tried.add(cand)
                self.counts[f"{APPEARANCE}_hypotheses"] += 1
                if self.try_link(node, cand, APPEARANCE):
                    break
        if cfg.proximity:
            for cand in self.proximity_candidates(node, exclude=tried):
                if not self.memory.nodes[cand].in_ram:  # an earlier link's retrieval moved it to long-term memory
                    continue
                self.counts[f"{PROXIMITY}_hypotheses"] += 1
                self.try_link(node, cand, PROXIMITY)
        if cfg.scan_proximity_on:
            self.try_scan_link(node)

    def try_scan_link(self, node: Node) -> bool:
        """Proximity by scan matching (scan_proximity.py) against the older nodes in working
        memory near the new node's estimate; kept only if the optimised graph agrees."""
        cfg = self.config
        here = self.graph.estimate(node.id)
        nodes = self.memory.nodes
        # Long-term memory too: a node there is read for its grid and goes back (space, unlike
        # appearance, needs no vocabulary entry).
        ids, stamps, estimates = self.positions.sync(nodes, self.graph)
        rows = np.flatnonzero(node.stamp - stamps >= cfg.scan_proximity_min_age)
        if not len(rows):
            return False
        old, poses = ids[rows], estimates[rows]
        near = np.hypot(poses[:, 0] - here[0], poses[:, 1] - here[1]) <= cfg.scan_proximity_radius
        if not near.any():
            return False
        self.counts[f"{SCAN}_hypotheses"] += 1
        settings = ScanLinkSettings(
            cfg.scan_proximity_radius,
            cfg.scan_proximity_min_age,
            cfg.scan_proximity_max_correction,
            cfg.scan_proximity_max_angle,
            cfg.scan_proximity_min_overlap,
            cfg.scan_proximity_max_rmse,
            (cfg.loop_sigma_linear, cfg.loop_sigma_linear, cfg.loop_sigma_angular),
            cfg.scan_proximity_min_constraining,
        )
        candidates = []
        # The nearest few: a corridor driven for the n-th time has n passes of nodes within the
        # radius, and the registration's cost (and the map's) would grow with every lap.
        distance = np.hypot(poses[:, 0] - here[0], poses[:, 1] - here[1])
        nearest = np.flatnonzero(near)[np.argsort(distance[near], kind="stable")]
        if cfg.scan_proximity_max_candidates:
            nearest = nearest[: cfg.scan_proximity_max_candidates]
        for k in np.sort(nearest):
            cand = nodes[old[k]]
            if not cand.in_ram:
                cand = Node(cand.id, cand.stamp, cand.odom, None, self.memory.grid(cand.id), None)
            candidates.append((cand, poses[k]))
        link = scan_link(node, here, candidates, settings)
        if link is None:
            self.counts[f"{SCAN}_rejected_verification"] += 1
            return False
        check = self._try_loop(node, link.anchor, link.delta, information=link.information)
        if not check.accepted:
            self.counts[f"{SCAN}_rejected_graph"] += 1
            return False
        self.counts[f"{SCAN}_accepted"] += 1
        if link.freed:
            self.counts[f"{SCAN}_one_direction"] += 1  # along a corridor: across-track and heading only
        self.memory.db.put_link(link.anchor, node.id, SCAN, pose_from_xyyaw(link.delta), link.information)
        return True

    def _try_loop(self, node: Node, anchor: int, delta: np.ndarray, **uncertainty) -> LoopCheck:
        """The graph's verdict on a link from `anchor` to the new node, the nodes in memory free."""
        free = self.free_nodes(node)
        check = self.graph.try_loop(
            anchor, node.id, delta, max_error=self.config.optimize_max_error, check="graph", free=free, **uncertainty
        )
        # A rejected try in working memory leaves every estimate as it was.
        if check.accepted:
            self.positions.refresh(self.graph, free)
        return check

    def free_nodes(self, node: Node) -> set[int]:
        """The nodes a loop try may move, as RTAB-Map's optimizeCurrentMap: short-term and working
        memory and the new node (the long-term nodes their edges reach are held), so a try costs
        what the memory's budget allows whatever the route's length."""
        return self.memory.wm | set(self.memory.stm) | {node.id}

    def proximity_candidates(self, node: Node, exclude: set[int]) -> list[int]:
        cfg = self.config
        nodes = self.memory.nodes
        ids = np.array([i for i in self.memory.wm if i not in exclude and nodes[i].in_ram], dtype=np.int64)
        if not len(ids):
            return []
        here = self.graph.estimate(node.id)
        poses = np.array([self.graph.estimate(i) for i in ids])
        dist = np.hypot(poses[:, 0] - here[0], poses[:, 1] - here[1])
        angle = np.abs(wrap_angle(poses[:, 2] - here[2]))
        near = (dist <= cfg.proximity_radius) & (angle <= cfg.proximity_max_angle)
        order = np.argsort(dist[near], kind="stable")
        return [int(i) for i in ids[near][order][: cfg.proximity_candidates]]

    def visual_link(self, query: Features, candidate: Features, min_support: int = 0) -> np.ndarray | None:
        """The query robot's pose in the candidate robot's frame (x, y, yaw) from their images, or
        None when PnP does not verify it, the motion is not planar, or fewer than `min_support`
        3D-3D matches hold it."""
        cfg = self.config
        min_inliers = cfg.min_inliers if self.min_inliers is None else self.min_inliers
        check = verify(query, candidate, self.intrinsics, min_inliers)
        if not check.accepted:
            return None
        transform = depth_held_transform(
            query, candidate, check.transform, self.intrinsics.fx, cfg.refine_3d, min_support, self.depth_noise
        )
        if transform is None:
            self.counts[UNHELD_BY_DEPTH] += 1
            return None
        return self.planar_link(transform)

    def try_link(self, node: Node, cand_id: int, source: str) -> bool:
        """Verify a hypothesis, add it to the graph, keep it only if the optimised graph agrees."""
        cfg = self.config
        candidate = self.memory.nodes[cand_id]
        # The new node is not yet in working memory, so none of its links moves it out; the candidate is in it.
        assert node.features is not None and candidate.features is not None
        delta = self.visual_link(node.features, candidate.features, min_support=cfg.loop_min_depth_support)
        if delta is None:
            self.counts[f"{source}_rejected_verification"] += 1
            return False
        linear, angular = noisy_link_sigmas(
            candidate.features.points, self.depth_noise, cfg.loop_sigma_linear, cfg.loop_sigma_angular
        )
        sigmas = np.array([linear, linear, angular])
        check = self._try_loop(node, cand_id, delta, sigmas=sigmas)
        if not check.accepted:
            self.counts[f"{source}_rejected_graph"] += 1
            return False
        self.counts[f"{source}_accepted"] += 1
        link_kind = "loop" if source == APPEARANCE else PROXIMITY
        self.memory.db.put_link(cand_id, node.id, link_kind, pose_from_xyyaw(delta), np.diag(1.0 / np.square(sigmas)))
        candidate.last_access = node.id
        self.memory.retrieve_around(cand_id)
        return True

    def planar_link(self, camera_transform: np.ndarray) -> np.ndarray | None:
        """Pose of the query robot in the candidate robot's frame as (x, y, yaw), or None if the
        verified camera motion is not planar (a sign of a wrong match)."""
        return planar_link(self.camera_in_base, camera_transform)
