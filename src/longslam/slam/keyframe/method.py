"""The keyframe method: a graph of RGB-D keyframes in the style of RTAB-Map, 3 DoF (x, y, yaw).

Each frame's motion comes from the shared front end (`longslam.slam.frontend`); a node keeps
the front end's pose of its frame (its "odometry"), ORB features with their 3D points, a local
occupancy grid and a few depth points. Consecutive nodes are linked by that odometry; loop closures
(`loops.py`) come from a visual bag of words over the nodes in working memory and from proximity
to the current estimate. Nodes beyond the working-memory budget go to a SQLite long-term memory
(`memory.py`) and come back when a loop closure lands next to them. The maps are assembled at
the end (`maps.py`), at the nodes' frames' final poses: every frame's pose from the front end's
smoother with the graph's accepted loop closures. This module is the per-frame loop that joins them.
"""

from __future__ import annotations

import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from longslam.core.errors import InputError
from longslam.core.frame import Frame
from longslam.core.geometry import CameraMount, compose_xyyaw, pose_from_xyyaw, relative_xyyaw
from longslam.core.memory_release import release_free_memory
from longslam.core.trajectory import Trajectory
from longslam.slam import stats
from longslam.slam.api import MethodContext, MethodSpec, Result, Table
from longslam.slam.features import Features, extract
from longslam.slam.frontend import FrameStep, FrontEnd
from longslam.slam.graph import ODOMETRY, PoseGraph
from longslam.slam.keyframe.config import KeyframeConfig
from longslam.slam.keyframe.loops import SOURCES, LoopCloser, counter_names
from longslam.slam.keyframe.maps import assemble_maps
from longslam.slam.keyframe.memory import KeyframeMemory, Node
from longslam.slam.keyframe.memory_db import MemoryDatabase
from longslam.slam.occupancy import depth_points_in_base, local_grid
from longslam.slam.place_recognition import Vocabulary
from longslam.slam.rows import Rows


class KeyframeMethod:
    name = "keyframe"

    def __init__(self, context: MethodContext, config: KeyframeConfig = KeyframeConfig()):
        self.config = config
        self.intrinsics = context.intrinsics
        self._own_dir: str | None = None
        folder = context.output_dir
        if folder is None:  # no run folder: long-term memory in a scratch folder, removed at finish
            self._own_dir = folder = tempfile.mkdtemp(prefix="longslam-ltm-")
        self.db_path = Path(folder) / "memory.db"
        self.db = MemoryDatabase(self.db_path)
        self.graph = PoseGraph()
        self.counts = {
            stats.FRAMES: 0,
            stats.NODES: 0,
            stats.FRAMES_WITHOUT_DEPTH: 0,
            "frames_no_features": 0,
            stats.ODOMETRY_JUMPS: 0,
            **{name: 0 for name in counter_names()},
            "nodes_transferred": 0,
            "nodes_retrieved": 0,
            stats.OPTIMIZATIONS: 0,
        }
        vocabulary = Vocabulary(self.config.word_distance, self.config.max_words, self.config.vocabulary_index)
        self.memory = KeyframeMemory(self.config, self.db, vocabulary, self._node_camera_poses, self.counts)
        self.loops: LoopCloser | None = None  # made at the first frame, when the camera mount is known
        self._mount: CameraMount | None = None  # the front end's, known at the first frame
        self.frontend = FrontEnd(context.intrinsics, config.frontend)
        # Beyond what the front end reads, only nodes (~1 Hz) read images.
        self.images_every_frame = self.frontend.images_every_frame
        self._node_frame: dict[int, int] = {}  # node id -> index of the frame it was made at
        self._last_node: Node | None = None
        # Per frame, in flat chunks rather than lists of small objects (slam/rows.py).
        self._frame_stamps = Rows()
        self._online = Rows((3,))  # every frame's online robot pose (x, y, yaw): its camera pose is made at the finish
        self._node_seconds: list[float] = []  # time to make each node (features, loops, memory)

    @property
    def nodes(self) -> dict[int, Node]:
        return self.memory.nodes

    def _node_camera_poses(self, node_id: int) -> tuple[np.ndarray, np.ndarray]:
        """A node's estimated and odometry camera poses (what the long-term memory stores)."""
        assert self._mount is not None  # placed at the first frame
        both = np.array([self.graph.estimate(node_id), self.nodes[node_id].odom])
        pose, odom = self._mount.to_camera(both)
        return pose, odom

    # --- per frame ---------------------------------------------------------------------------
    def work_ahead(self, frame: Frame) -> None:
        """On the engine's read-ahead thread, before this frame's step: the front end's part."""
        self.frontend.work_ahead(frame)

    def step(self, frame: Frame) -> np.ndarray:
        motion = self._frontend_motion(frame)
        odom = motion.xyyaw
        self.counts[stats.FRAMES] += 1
        if self._is_new_node(frame.timestamp, odom):
            self._node_frame[len(self.nodes)] = len(self._frame_stamps)
            started = time.perf_counter()
            self._add_node(frame, motion)
            self._node_seconds.append(time.perf_counter() - started)
        node = self._last_node
        assert node is not None and self._mount is not None  # the first frame made a node and placed the mount
        xyyaw = compose_xyyaw(self.graph.estimate(node.id), relative_xyyaw(node.odom, odom))
        self._frame_stamps.append(frame.timestamp)
        self._online.append(xyyaw)
        return self._mount.to_camera(xyyaw[None])[0]

    def _frontend_motion(self, frame: Frame) -> FrameStep:
        """The front end's step of this frame: its online pose is the node's "odometry"."""
        pose = self.frontend.step(frame)
        if self._mount is None:
            assert self.frontend.mount is not None  # its first step placed it
            self._start(self.frontend.mount)
        self.counts[stats.ODOMETRY_JUMPS] = self.frontend.counts["odometry_jumps"]
        return pose

    def _start(self, mount: CameraMount) -> None:
        """At the first frame: where the camera sits, and the loop closer that needs it."""
        self._mount = mount
        self._camera_in_base = mount.camera_in_base
        self.loops = LoopCloser(
            self.config, self.intrinsics, self.graph, self.memory, self._camera_in_base, self.counts
        )

    def _is_new_node(self, stamp: float, odom: np.ndarray) -> bool:
        last = self._last_node
        if last is None:
            return True
        if stamp - last.stamp < 1.0 / self.config.detection_rate - 1e-6:
            return False
        delta = relative_xyyaw(last.odom, odom)
        return np.hypot(delta[0], delta[1]) >= self.config.linear_update or abs(delta[2]) >= self.config.angular_update

    # --- nodes ---------------------------------------------------------------------------------
    def _add_node(self, frame: Frame, motion: FrameStep) -> None:
        odom = motion.xyyaw
        cfg = self.config
        node_id = len(self.nodes)
        depth = np.asarray(frame.depth, dtype=np.float32)
        # Grid and points only where the frame's depth noise allows (the front end's rule); loop
        # features to where their noise, weighed in the verification, still places them.
        depths = motion.depths(depth)
        depth, loop_depth, depth_noise = depths.trusted, depths.loops, depths.loop_noise
        min_inliers = depths.loop_min_inliers(cfg.min_inliers)
        has_depth = bool(np.any(np.isfinite(loop_depth) & (loop_depth > 0)))
        if not has_depth:
            self.counts[stats.FRAMES_WITHOUT_DEPTH] += 1
        if self.loops is not None:
            self.loops.depth_noise = depth_noise
            self.loops.min_inliers = min_inliers
        features = extract(frame.rgb, loop_depth, self.intrinsics, cfg.max_features) if has_depth else Features.empty()
        if has_depth and len(features) == 0:
            self.counts["frames_no_features"] += 1
        features = self._drop_floor_and_ceiling_points(features)
        grid = local_grid(
            depth,
            self.intrinsics,
            self._camera_in_base,
            cfg.grid_cell,
            cfg.grid_range,
            cfg.obstacle_min_height,
            cfg.obstacle_max_height,
            cfg.grid_stride,
        )
        points = depth_points_in_base(depth, self.intrinsics, self._camera_in_base, cfg.cloud_stride).astype(np.float32)
        node = Node(node_id, frame.timestamp, odom.copy(), features, grid, points, last_access=node_id)
        self.memory.add(node)

        previous = self._last_node
        if previous is None:
            self.graph.add_node(node_id, odom)
        else:
            delta = relative_xyyaw(previous.odom, odom)
            sigmas = self._odometry_sigmas(delta, node.stamp - previous.stamp)
            self.graph.add_node(node_id, compose_xyyaw(self.graph.estimate(previous.id), delta))
            self.graph.add_odometry(previous.id, node_id, delta, sigmas)
            self.db.put_link(previous.id, node_id, "odometry", pose_from_xyyaw(delta), np.diag(1.0 / np.square(sigmas)))
        self._last_node = node
        self.counts[stats.NODES] += 1

        # One dictionary search per node: the words serve the query and then the index.
        words = self.memory.vocabulary.quantise(features.descriptors, grow=True)
        if features.valid.sum() >= min_inliers:
            assert self.loops is not None  # made at the first frame, before its node
            self.loops.detect(node, words)
            self.counts[stats.OPTIMIZATIONS] = self.graph.optimizations
        self.memory.admit(node_id, words)

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
        rot = max(cfg.odom_heading_floor, cfg.odom_sigma_angular * max(dt, 0.0))
        return np.array([forward, max(cfg.odom_sigma_min, cfg.odom_sigma_lateral * forward), rot])

    # --- the end -------------------------------------------------------------------------------
    def _frontend_final(self) -> np.ndarray:
        """Every frame's pose from the front end's smoother, with the graph's accepted loop
        closures (node to node) added as constraints between the nodes' frames."""
        self.frontend.add_graph_edges([e for e in self.graph.edges if e.kind != ODOMETRY], self._node_frame)
        held = {
            frame: self.graph.estimate(node_id)
            for node_id, frame in self._node_frame.items()
            if self.graph.has_node(node_id)
        }
        return self.frontend.final_trajectory(held)

    def memory_bytes(self) -> dict[str, int]:
        return {**self.memory.memory_bytes(), "graph": 3 * 8 * self.graph.num_nodes + 64 * len(self.graph.edges)}

    def finish(self) -> Result:
        if not self._frame_stamps:
            raise InputError("the keyframe method got no frames")
        if self.graph.num_loops:
            self.graph.optimize(warm_start=True)
            self.counts[stats.OPTIMIZATIONS] = self.graph.optimizations
        map_bytes = self.memory_bytes()
        census = self.memory.census()
        vocabulary = {
            "vocabulary_words": self.memory.vocabulary.n_words,
            "vocabulary_index_rebuilds": self.memory.vocabulary.index_rebuilds,
        }
        # Mapping is over: every node to the database and the vocabulary dropped before the final
        # smoother, the finish's peak, is built; the maps read the nodes' grids back.
        self.memory.flush()
        self.memory.release_search()
        release_free_memory()
        final = self._frontend_final()
        assert self._mount is not None  # frames were given
        poses = self._mount.to_camera(final)
        stamps = self._frame_stamps.array()
        trajectory = Trajectory(stamps, poses, source="keyframe")
        online = Trajectory(stamps, self._mount.to_camera(self._online.array()), source="keyframe online")

        grid_map, cloud = assemble_maps(
            sorted(self.nodes),
            lambda node_id: final[self._node_frame[node_id]],
            self.memory.grid_and_points,
            self._mount,
            self.config.grid_cell,
            self.config.cloud_voxel,
            scratch_dir=self.db_path.parent,
            grid_reach=self.config.grid_range,
        )

        # The database ends holding every node at its optimised pose, so a user can reopen it.
        self.db.update_poses({i: self._node_camera_poses(i)[0] for i in self.nodes})
        counts = self.counts
        run_stats: dict[str, object] = dict(counts)
        run_stats.update(
            {
                stats.LOOP_HYPOTHESES: sum(counts[f"{p}_hypotheses"] for p in SOURCES),
                stats.LOOPS_ACCEPTED: sum(counts[f"{p}_accepted"] for p in SOURCES),
                stats.LOOPS_REJECTED: sum(
                    counts[f"{p}_rejected_{why}"] for p in SOURCES for why in ("verification", "graph")
                ),
                stats.MAP_BYTES: map_bytes,
                stats.CAMERA_HEIGHT: self._mount.camera_height,
                **census,
                **vocabulary,
                "graph_loops": self.graph.num_loops,
                "database": str(self.db_path) if self._own_dir is None else None,
            }
        )
        run_stats["frontend"] = self.frontend.stats
        # The database names itself by file name: its folder is still a temporary one while the
        # run is under way (stats.json gets the final path from the run engine).
        self.db.set_statistics({**run_stats, "database": self.db_path.name})
        self.db.close()
        if self._own_dir is not None:
            shutil.rmtree(self._own_dir, ignore_errors=True)
        # Per node (nodes.csv), so that a benchmark can tell whether its cost grows with the route.
        nodes = Table(
            ("node", "time_ms"),
            np.column_stack(
                [np.arange(len(self._node_seconds)), 1000.0 * np.asarray(self._node_seconds, dtype=np.float64)]
            ),
        )
        return Result(
            trajectory=trajectory,
            online=online,
            grid=grid_map,
            cloud=cloud,
            stats=run_stats,
            tables={"loops": self.frontend.loop_table(), "frontend": self.frontend.frame_table(), "nodes": nodes},
        )


SPEC = MethodSpec(
    "keyframe", KeyframeConfig, KeyframeMethod, "RTAB-Map's design: keyframes, bag of words, SQLite memory"
)
