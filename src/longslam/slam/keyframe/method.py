"""The keyframe method: a graph of RGB-D keyframes in the style of RTAB-Map, 3 DoF (x, y, yaw).

Each node keeps its odometry pose, ORB features with their 3D points, a local occupancy grid
and a few depth points. Consecutive nodes are linked by the wheel odometry; loop closures come
from a visual bag of words over the nodes in working memory and from proximity to the current
estimate, each verified by PnP RANSAC and kept only if the optimised graph agrees with it
(RGBD/OptimizeMaxError). Nodes beyond the working-memory budget go to a SQLite long-term memory
and come back when a loop closure lands next to them.
"""

from __future__ import annotations

import shutil
import tempfile
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from longslam.errors import InputError
from longslam.frame import Frame
from longslam.geometry import (
    base_to_camera, camera_poses_from_planar, invert, planar_from_camera_poses, planar_poses, wrap_angle,
)
from longslam.slam.base import MethodContext, Result, frame_odometry
from longslam.slam.features import Features, extract
from longslam.slam.keyframe.config import KeyframeConfig
from longslam.slam.memory_db import MemoryDatabase
from longslam.slam.occupancy import LocalGrid, assemble, depth_points_in_base, local_grid
from longslam.slam.params import config_from_params
from longslam.slam.place_recognition import Vocabulary, refine_3d, verify
from longslam.slam.pose_graph import PoseGraph2D, compose_xyyaw, relative_xyyaw
from longslam.slam.registry import METHODS
from longslam.trajectory import Trajectory

# A verified loop transform must be planar: the camera neither rises nor tilts on this robot.
MAX_LOOP_Z = 0.3  # m
MAX_LOOP_TILT = 0.2  # rad


@dataclass
class Node:
    id: int
    stamp: float
    odom: np.ndarray  # (3,) odometry x, y, yaw (jumps removed)
    features: Features | None  # None while the node is in long-term memory
    grid: LocalGrid | None
    points: np.ndarray | None  # (M, 3) float32 depth points in the robot frame, for the 3D map
    last_access: int = 0  # node count when last created, matched or retrieved (LRU for transfers)

    @property
    def in_ram(self) -> bool:
        return self.features is not None


class KeyframeMethod:
    name = "keyframe"

    def __init__(self, context: MethodContext, params: dict[str, Any]):
        self.config = config_from_params(KeyframeConfig, params, self.name)
        self.intrinsics = context.intrinsics
        self._own_dir: str | None = None
        folder = context.output_dir
        if folder is None:  # no run folder: long-term memory in a scratch folder, removed at finish
            self._own_dir = folder = tempfile.mkdtemp(prefix="longslam-ltm-")
        self.db_path = Path(folder) / "memory.db"
        self.db = MemoryDatabase(self.db_path)
        self.vocabulary = Vocabulary(self.config.word_distance, self.config.max_words)
        self.graph = PoseGraph2D()
        self.nodes: dict[int, Node] = {}
        self.estimates: dict[int, np.ndarray] = {}
        self.stm: deque[int] = deque()
        self.wm: set[int] = set()
        self._camera_in_base: np.ndarray | None = None
        self._floor_z = 0.0
        self._camera_height = 0.0
        self._raw_prev: np.ndarray | None = None
        self._odom: np.ndarray | None = None  # corrected odometry of the latest frame
        self._last_node: Node | None = None
        self._frame_stamps: list[float] = []
        self._frame_node: list[int] = []
        self._frame_odom: list[np.ndarray] = []
        self._online: list[np.ndarray] = []
        self.counts = {
            "frames": 0, "nodes": 0, "frames_no_depth": 0, "frames_no_features": 0, "odometry_jumps": 0,
            "loop_hypotheses": 0, "loops_accepted": 0, "loops_rejected_verification": 0,
            "loops_rejected_graph": 0, "proximity_hypotheses": 0, "proximity_accepted": 0,
            "proximity_rejected_verification": 0, "proximity_rejected_graph": 0,
            "nodes_transferred": 0, "nodes_retrieved": 0, "optimizations": 0,
            "neighbor_links_refined": 0, "neighbor_links_odometry": 0, "neighbor_links_rejected": 0,
        }

    # --- per frame ---------------------------------------------------------------------------
    def step(self, frame: Frame) -> np.ndarray:
        odom = self._corrected_odometry(frame_odometry(frame, self.name))
        self.counts["frames"] += 1
        if self._is_new_node(frame.timestamp, odom):
            self._add_node(frame, odom)
        node = self._last_node
        xyyaw = compose_xyyaw(self.estimates[node.id], relative_xyyaw(node.odom, odom))
        pose = camera_poses_from_planar(xyyaw[None], self._camera_height, self._floor_z)[0]
        self._frame_stamps.append(frame.timestamp)
        self._frame_node.append(node.id)
        self._frame_odom.append(odom)
        self._online.append(pose)
        return pose

    def _corrected_odometry(self, camera_pose: np.ndarray) -> np.ndarray:
        """Planar odometry with jumps (a step no robot makes in one frame) replaced by no motion."""
        if self._camera_in_base is None:
            self._camera_height = self.config.camera_height or float(camera_pose[2, 3])
            self._floor_z = float(camera_pose[2, 3]) - self._camera_height
            self._camera_in_base = base_to_camera(self._camera_height)
        raw = planar_from_camera_poses(camera_pose[None], self._camera_height)[0]
        if self._odom is None:
            self._raw_prev, self._odom = raw, raw
            return raw
        delta = relative_xyyaw(self._raw_prev, raw)
        self._raw_prev = raw
        if np.hypot(delta[0], delta[1]) > self.config.jump_distance or abs(delta[2]) > self.config.jump_angle:
            self.counts["odometry_jumps"] += 1
            delta = np.zeros(3)
        self._odom = compose_xyyaw(self._odom, delta)
        return self._odom

    def _is_new_node(self, stamp: float, odom: np.ndarray) -> bool:
        last = self._last_node
        if last is None:
            return True
        if stamp - last.stamp < 1.0 / self.config.detection_rate - 1e-6:
            return False
        delta = relative_xyyaw(last.odom, odom)
        return np.hypot(delta[0], delta[1]) >= self.config.linear_update or abs(delta[2]) >= self.config.angular_update

    # --- nodes ---------------------------------------------------------------------------------
    def _add_node(self, frame: Frame, odom: np.ndarray) -> None:
        cfg = self.config
        node_id = len(self.nodes)
        depth = np.asarray(frame.depth, dtype=np.float32)
        has_depth = bool(np.any(np.isfinite(depth) & (depth > 0)))
        if not has_depth:
            self.counts["frames_no_depth"] += 1
        features = extract(frame.rgb, depth, self.intrinsics, cfg.max_features) if has_depth else Features.empty()
        if has_depth and len(features) == 0:
            self.counts["frames_no_features"] += 1
        features = self._drop_floor_and_ceiling_points(features)
        grid = local_grid(depth, self.intrinsics, self._camera_in_base, cfg.grid_cell, cfg.grid_range,
                          cfg.obstacle_min_height, cfg.obstacle_max_height)
        points = depth_points_in_base(depth, self.intrinsics, self._camera_in_base, cfg.cloud_stride).astype(np.float32)
        node = Node(node_id, frame.timestamp, odom.copy(), features, grid, points, last_access=node_id)
        self.nodes[node_id] = node

        previous = self._last_node
        if previous is None:
            self.estimates[node_id] = odom.copy()
            self.graph.add_node(node_id, odom)
        else:
            delta = relative_xyyaw(previous.odom, odom)
            sigmas = self._odometry_sigmas(delta, node.stamp - previous.stamp)
            if cfg.neighbor_refining:
                delta, sigmas = self._refine_neighbor_link(previous, node, delta, sigmas)
            self.estimates[node_id] = compose_xyyaw(self.estimates[previous.id], delta)
            self.graph.add_node(node_id, self.estimates[node_id])
            self.graph.add_odometry(previous.id, node_id, delta, sigmas)
            self.db.put_link(previous.id, node_id, "odometry", _planar_matrix(delta), np.diag(1.0 / np.square(sigmas)))
        self._last_node = node
        self.counts["nodes"] += 1

        # One dictionary search per node: the words serve the query and then the index. The node
        # joins the index after its own query, so it never matches itself.
        words = self.vocabulary.quantise(features.descriptors, grow=True)
        if features.valid.sum() >= cfg.min_inliers:
            self._detect_loops(node, words)
        self.vocabulary.add_words(node_id, words)
        self.stm.append(node_id)
        while len(self.stm) > cfg.stm_size:
            self.wm.add(self.stm.popleft())
        self._enforce_memory_budget()

    def _refine_neighbor_link(self, previous: Node, node: Node, delta: np.ndarray, sigmas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """RGBD/NeighborLinkRefining: replace the wheel odometry between consecutive nodes by
        the visual transform when PnP verifies it and it stays near the odometry, so that the
        odometry's scale and heading bias is corrected on first visits too, not only at loops."""
        cfg = self.config
        if previous.features is None or len(previous.features) == 0 or len(node.features) == 0:
            return delta, sigmas
        check = verify(node.features, previous.features, self.intrinsics, cfg.min_inliers)
        visual = None
        if check.accepted:
            visual = self._planar_link(refine_3d(node.features, previous.features, check.transform) if cfg.refine_3d else check.transform)
        if visual is None:
            self.counts["neighbor_links_odometry"] += 1
            return delta, sigmas
        step = float(np.hypot(delta[0], delta[1]))
        off = float(np.hypot(*(visual[:2] - delta[:2])))
        if off > cfg.refine_max_offset * max(step, 1.0) or abs(wrap_angle(visual[2] - delta[2])) > cfg.refine_max_angle:
            self.counts["neighbor_links_rejected"] += 1
            return delta, sigmas
        self.counts["neighbor_links_refined"] += 1
        return visual, np.array([cfg.loop_sigma_linear, cfg.loop_sigma_linear, cfg.loop_sigma_angular])

    def _drop_floor_and_ceiling_points(self, features: Features) -> Features:
        """Keep 3D points only between `anchor_min_height` and `anchor_max_height` above the floor.

        Floor tiles and ceiling panels repeat every half metre or so: PnP anchored on them can
        lock onto a copy one or two tiles away, a wrong loop that the graph check may not catch.
        Those keypoints still count as visual words; they just do not anchor a transform.
        """
        if not len(features):
            return features
        points = features.points.astype(np.float64)
        height = points @ self._camera_in_base[2, :3] + self._camera_in_base[2, 3]
        keep = (height >= self.config.anchor_min_height) & (height <= self.config.anchor_max_height)
        anchored = np.where(keep[:, None], features.points, np.float32(np.nan)).astype(np.float32)
        return Features(features.keypoints, features.descriptors, anchored)

    def _odometry_sigmas(self, delta: np.ndarray, dt: float) -> np.ndarray:
        cfg = self.config
        forward = max(cfg.odom_sigma_min, cfg.odom_sigma_linear * float(np.hypot(delta[0], delta[1])))
        rot = max(cfg.odom_sigma_min, cfg.odom_sigma_angular * max(dt, 0.0))
        return np.array([forward, max(cfg.odom_sigma_min, cfg.odom_sigma_lateral * forward), rot])

    # --- loop closure --------------------------------------------------------------------------
    def _detect_loops(self, node: Node, words: np.ndarray) -> None:
        cfg = self.config
        searchable = sorted(self.wm)
        tried: set[int] = set()
        if searchable:
            for cand, score in self.vocabulary.query_words(words, searchable, top_k=cfg.loop_candidates):
                if score < cfg.loop_threshold:
                    break
                tried.add(cand)
                self.counts["loop_hypotheses"] += 1
                if self._try_link(node, cand, "loop"):
                    break  # one appearance loop per node: the graph is re-optimised for each
        if cfg.proximity:
            for cand in self._proximity_candidates(node, exclude=tried):
                self.counts["proximity_hypotheses"] += 1
                self._try_link(node, cand, "proximity")

    def _proximity_candidates(self, node: Node, exclude: set[int]) -> list[int]:
        cfg = self.config
        ids = np.array([i for i in self.wm if i not in exclude and self.nodes[i].in_ram], dtype=np.int64)
        if not len(ids):
            return []
        here = self.estimates[node.id]
        poses = np.array([self.estimates[i] for i in ids])
        dist = np.hypot(poses[:, 0] - here[0], poses[:, 1] - here[1])
        angle = np.abs(wrap_angle(poses[:, 2] - here[2]))
        near = (dist <= cfg.proximity_radius) & (angle <= cfg.proximity_max_angle)
        order = np.argsort(dist[near], kind="stable")
        return [int(i) for i in ids[near][order][: cfg.proximity_candidates]]

    def _try_link(self, node: Node, cand_id: int, kind: str) -> bool:
        """Verify a hypothesis, add it to the graph, keep it only if the optimised graph agrees."""
        cfg = self.config
        prefix = "loops" if kind == "loop" else "proximity"
        candidate = self.nodes[cand_id]
        check = verify(node.features, candidate.features, self.intrinsics, cfg.min_inliers)
        delta = None
        if check.accepted:
            transform = refine_3d(node.features, candidate.features, check.transform) if cfg.refine_3d else check.transform
            delta = self._planar_link(transform)
        if delta is None:
            self.counts[f"{prefix}_rejected_verification"] += 1
            return False
        sigmas = np.array([cfg.loop_sigma_linear, cfg.loop_sigma_linear, cfg.loop_sigma_angular])
        edge = self.graph.add_loop(cand_id, node.id, delta, sigmas, robust=False)
        self._optimize()
        worst = max((e for e in self.graph.edge_errors(None)), key=lambda e: max(e.translation_error, e.rotation_error))
        if max(worst.translation_error, worst.rotation_error) > cfg.optimize_max_error:
            self.graph.remove_edge(edge)
            self._optimize()
            self.counts[f"{prefix}_rejected_graph"] += 1
            return False
        self.counts["loops_accepted" if kind == "loop" else "proximity_accepted"] += 1
        self.db.put_link(cand_id, node.id, kind, _planar_matrix(delta), np.diag(1.0 / np.square(sigmas)))
        candidate.last_access = node.id
        self._retrieve_around(cand_id)
        return True

    def _planar_link(self, camera_transform: np.ndarray) -> np.ndarray | None:
        """Pose of the query robot in the candidate robot's frame as (x, y, yaw), or None if the
        verified camera motion is not planar (a sign of a wrong match)."""
        base = self._camera_in_base @ camera_transform @ invert(self._camera_in_base)
        tilt = np.arccos(np.clip(base[2, 2], -1.0, 1.0))
        if abs(base[2, 3]) > MAX_LOOP_Z or tilt > MAX_LOOP_TILT:
            return None
        return np.array([base[0, 3], base[1, 3], np.arctan2(base[1, 0], base[0, 0])])

    def _optimize(self) -> None:
        result = self.graph.optimize(warm_start=True)
        self.counts["optimizations"] += 1
        for node_id, xyyaw in result.items():
            self.estimates[node_id] = np.asarray(xyyaw)

    # --- memory management ---------------------------------------------------------------------
    def _enforce_memory_budget(self) -> None:
        budget = self.config.wm_max_nodes
        if budget <= 0:
            return
        while len(self.wm) > budget:
            oldest = min(self.wm, key=lambda i: (self.nodes[i].last_access, i))
            self._transfer(oldest)

    def _transfer(self, node_id: int, count: bool = True) -> None:
        """Working memory -> long-term memory: the node's data go to the database and leave RAM."""
        node = self.nodes[node_id]
        arrays = {
            "keypoints": node.features.keypoints, "descriptors": node.features.descriptors,
            "points3d": node.features.points, "grid_obstacles": node.grid.obstacles,
            "grid_free": node.grid.free, "cloud": node.points,
        }
        pose = camera_poses_from_planar(self.estimates[node_id][None], self._camera_height, self._floor_z)[0]
        odom = camera_poses_from_planar(node.odom[None], self._camera_height, self._floor_z)[0]
        self.db.put_node(node_id, node.stamp, pose, odom, arrays, weight=node.last_access)
        self.vocabulary.remove(node_id)
        self.wm.discard(node_id)
        node.features = node.grid = node.points = None
        if count:
            self.counts["nodes_transferred"] += 1

    def _load(self, node_id: int) -> tuple[Features, LocalGrid, np.ndarray]:
        stored = self.db.get_node(node_id).arrays
        features = Features(stored["keypoints"], stored["descriptors"], stored["points3d"])
        grid = LocalGrid(stored["grid_obstacles"], stored["grid_free"], self.config.grid_cell)
        return features, grid, stored["cloud"]

    def _retrieve_around(self, node_id: int) -> None:
        """Bring back up to max_retrieved long-term nodes next to a loop closure (graph neighbours)."""
        brought = 0
        for offset in (1, -1, 2, -2, 3, -3):
            if brought >= self.config.max_retrieved:
                break
            other = self.nodes.get(node_id + offset)
            if other is None or other.in_ram:
                continue
            other.features, other.grid, other.points = self._load(other.id)
            other.last_access = len(self.nodes)
            self.vocabulary.add(other.id, other.features.descriptors)
            self.wm.add(other.id)
            brought += 1
            self.counts["nodes_retrieved"] += 1
        self._enforce_memory_budget()

    # --- the end -------------------------------------------------------------------------------
    def _final_planar_poses(self) -> np.ndarray:
        """Each frame's odometry relative to its keyframe, composed onto the keyframe's optimised
        pose. With `interpolate_corrections`, the frame is also placed from the next keyframe
        and the two are blended by time, so the correction the graph makes between two
        keyframes is spread over the frames between them instead of landing as a jump."""
        frame_node = np.array(self._frame_node)
        frame_odom = np.array(self._frame_odom)
        stamps = np.array(self._frame_stamps)
        own = np.array([compose_xyyaw(self.estimates[k], relative_xyyaw(self.nodes[k].odom, o))
                        for k, o in zip(frame_node, frame_odom)])
        if not self.config.interpolate_corrections:
            return own
        out = own.copy()
        last_node = max(self.nodes)
        for i in np.flatnonzero(frame_node < last_node):
            current, following = self.nodes[frame_node[i]], self.nodes[frame_node[i] + 1]
            span = following.stamp - current.stamp
            w = (stamps[i] - current.stamp) / span if span > 0 else 0.0
            other = compose_xyyaw(self.estimates[following.id], relative_xyyaw(following.odom, frame_odom[i]))
            out[i, :2] = (1.0 - w) * own[i, :2] + w * other[:2]
            out[i, 2] = wrap_angle(own[i, 2] + w * wrap_angle(other[2] - own[i, 2]))
        return out

    def memory_bytes(self) -> dict[str, int]:
        in_ram = [n for n in self.nodes.values() if n.in_ram]
        return {
            "features": sum(n.features.nbytes for n in in_ram),
            "local_grids": sum(n.grid.nbytes for n in in_ram),
            "node_points": sum(n.points.nbytes for n in in_ram),
            "vocabulary": int(self.vocabulary.nbytes),
            "graph": 3 * 8 * len(self.estimates) + 64 * len(self.graph.edges),
            "database_on_disk": self.db.size_bytes(),
        }

    def finish(self) -> Result:
        if not self._frame_stamps:
            raise InputError("the keyframe method got no frames")
        if self.graph.num_loops:
            self._optimize()
        final = self._final_planar_poses()
        poses = camera_poses_from_planar(final, self._camera_height, self._floor_z)
        trajectory = Trajectory(np.array(self._frame_stamps), poses, source="keyframe")
        online = Trajectory(np.array(self._frame_stamps), np.array(self._online), source="keyframe online")

        map_bytes = self.memory_bytes()
        wm_nodes, stm_nodes = len(self.wm), len(self.stm)
        ltm_nodes = sum(1 for n in self.nodes.values() if not n.in_ram)
        grids, clouds, node_poses = [], [], []
        for node_id in sorted(self.nodes):
            node = self.nodes[node_id]
            grid, points = (node.grid, node.points) if node.in_ram else self._load(node_id)[1:]
            grids.append(grid)
            # Node points are in the robot base frame (z up, on the floor), so they move by the
            # base's planar pose, not by a camera-frame pose (OpenCV axes would scramble them).
            base_pose = planar_poses(self.estimates[node_id][None], z=self._floor_z)[0]
            clouds.append(points @ base_pose[:3, :3].T + base_pose[:3, 3])
            node_poses.append(self.estimates[node_id])
        grid_map = assemble(grids, np.array(node_poses), self.config.grid_cell)
        cloud = _voxel_filter(np.concatenate(clouds) if clouds else np.zeros((0, 3)), self.config.cloud_voxel)

        # The database ends holding every node at its optimised pose, so a user can reopen it.
        for node_id in sorted(self.wm | set(self.stm)):
            self._transfer(node_id, count=False)
        self.db.update_poses({i: camera_poses_from_planar(self.estimates[i][None], self._camera_height, self._floor_z)[0]
                              for i in self.nodes})
        stats = dict(self.counts)
        stats.update(
            wm_nodes=wm_nodes, stm_nodes=stm_nodes, ltm_nodes=ltm_nodes,
            vocabulary_words=self.vocabulary.n_words, graph_loops=self.graph.num_loops,
            map_bytes=map_bytes,
            database=str(self.db_path) if self._own_dir is None else None,
        )
        self.db.set_statistics(stats)
        self.db.close()
        if self._own_dir is not None:
            shutil.rmtree(self._own_dir, ignore_errors=True)
        return Result(trajectory=trajectory, online=online, grid=grid_map, cloud=cloud, stats=stats)


def _planar_matrix(xyyaw: np.ndarray) -> np.ndarray:
    c, s = np.cos(xyyaw[2]), np.sin(xyyaw[2])
    m = np.eye(4)
    m[:2, :2] = [[c, -s], [s, c]]
    m[:2, 3] = xyyaw[:2]
    return m


def _voxel_filter(points: np.ndarray, voxel: float) -> np.ndarray:
    """One point (the centroid) per occupied voxel."""
    if not len(points):
        return np.zeros((0, 3), np.float32)
    keys = np.floor(points / voxel).astype(np.int64)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    sums = np.zeros((len(counts), 3))
    np.add.at(sums, inverse.ravel(), points)
    return (sums / counts[:, None]).astype(np.float32)


METHODS.register("keyframe", KeyframeMethod)
