"""Loop closure for the keyframe method: hypotheses, verification, and the graph's verdict.

Hypotheses come from the visual vocabulary (tf-idf over working memory, Kp/ and Rtabmap/
LoopThr) and from proximity to the current estimate (RGBD/ProximityBySpace). Each is verified
by PnP RANSAC (Vis/MinInliers), polished on 3D-3D matches (Vis/EstimationType 0), must be planar,
and is kept only if the optimised graph agrees with it (RGBD/OptimizeMaxError).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from longslam.frame import Intrinsics
from longslam.geometry import pose_from_xyyaw, wrap_angle
from longslam.slam.features import Features
from longslam.slam.graph import PoseGraph
from longslam.slam.keyframe.config import KeyframeConfig
from longslam.slam.keyframe.memory import KeyframeMemory, Node
from longslam.slam.keyframe.scan_proximity import ScanLinkSettings, scan_link
from longslam.slam.place_recognition import planar_link, refine_3d, verify

APPEARANCE, PROXIMITY, SCAN = "appearance", "proximity", "scan_proximity"
SOURCES = (APPEARANCE, PROXIMITY, SCAN)


def counter_names() -> list[str]:
    """The per-source counters this module keeps (hypotheses, accepted, rejected and why)."""
    return [f"{s}_{what}" for s in SOURCES
            for what in ("hypotheses", "accepted", "rejected_verification", "rejected_graph")] + [f"{SCAN}_one_direction"]


@dataclass
class LoopCloser:
    config: KeyframeConfig
    intrinsics: Intrinsics
    graph: PoseGraph  # the keyframe graph, whose verdict keeps or drops a closure
    memory: KeyframeMemory  # whose working memory is searched and whose database keeps the links
    camera_in_base: np.ndarray  # (4, 4)
    counts: dict[str, int]  # the method's counters, which this updates

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
        old = [i for i in nodes if node.stamp - nodes[i].stamp >= cfg.scan_proximity_min_age]
        if not old:
            return False
        poses = np.array([self.graph.estimate(i) for i in old])
        near = np.hypot(poses[:, 0] - here[0], poses[:, 1] - here[1]) <= cfg.scan_proximity_radius
        if not near.any():
            return False
        self.counts[f"{SCAN}_hypotheses"] += 1
        settings = ScanLinkSettings(cfg.scan_proximity_radius, cfg.scan_proximity_min_age, cfg.scan_proximity_max_correction,
                                    cfg.scan_proximity_max_angle, cfg.scan_proximity_min_overlap, cfg.scan_proximity_max_rmse,
                                    (cfg.loop_sigma_linear, cfg.loop_sigma_linear, cfg.loop_sigma_angular),
                                    cfg.scan_proximity_min_constraining)
        candidates = []
        for k in np.flatnonzero(near):
            cand = nodes[old[k]]
            if not cand.in_ram:
                cand = Node(cand.id, cand.stamp, cand.odom, None, self.memory.grid(cand.id), None)
            candidates.append((cand, poses[k]))
        link = scan_link(node, here, candidates, settings)
        if link is None:
            self.counts[f"{SCAN}_rejected_verification"] += 1
            return False
        check = self.graph.try_loop(link.anchor, node.id, link.delta, information=link.information,
                                    max_error=cfg.optimize_max_error, check="graph")
        if not check.accepted:
            self.counts[f"{SCAN}_rejected_graph"] += 1
            return False
        self.counts[f"{SCAN}_accepted"] += 1
        if link.freed:
            self.counts[f"{SCAN}_one_direction"] += 1  # along a corridor: across-track and heading only
        self.memory.db.put_link(link.anchor, node.id, SCAN, pose_from_xyyaw(link.delta), link.information)
        return True

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

    def visual_link(self, query: Features, candidate: Features) -> np.ndarray | None:
        """The query robot's pose in the candidate robot's frame (x, y, yaw) from their images, or
        None when PnP does not verify it or the motion is not planar."""
        cfg = self.config
        check = verify(query, candidate, self.intrinsics, cfg.min_inliers)
        if not check.accepted:
            return None
        transform = refine_3d(query, candidate, check.transform) if cfg.refine_3d else check.transform
        return self.planar_link(transform)

    def try_link(self, node: Node, cand_id: int, source: str) -> bool:
        """Verify a hypothesis, add it to the graph, keep it only if the optimised graph agrees."""
        cfg = self.config
        candidate = self.memory.nodes[cand_id]
        delta = self.visual_link(node.features, candidate.features)
        if delta is None:
            self.counts[f"{source}_rejected_verification"] += 1
            return False
        sigmas = np.array([cfg.loop_sigma_linear, cfg.loop_sigma_linear, cfg.loop_sigma_angular])
        check = self.graph.try_loop(cand_id, node.id, delta, sigmas=sigmas, max_error=cfg.optimize_max_error, check="graph")
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
