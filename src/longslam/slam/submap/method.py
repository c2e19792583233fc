"""The `submap` method: Voxgraph's design, TSDF submaps in a pose graph.

- Each frame's motion comes from the shared front end (`longslam.slam.frontend`). Its depth is
  integrated into the active submap's TSDF at the front end's pose relative to the submap's origin (the robot's floor
  pose at the submap's first frame).
- Every `submap_interval` seconds of frame time the active submap is finished and a new one
  starts. A finished submap keeps its compacted TSDF (int8 distances), a sample of its
  iso-surface points for registration and its bounding box; nothing else.
- The pose graph's nodes are the submap origins (x, y, yaw on the floor). Edges: odometry between
  consecutive submaps; registration between the new finished submap and every finished submap
  whose bounding box overlaps it (its surface points aligned in the other's distance field, the
  result checked before it enters the graph); optionally loop closures from visual place
  recognition (the `place_recognition` module shared with the keyframe method; on by default
  with the fused front end, off in "wheel" mode as in the paper). GTSAM optimises
  it, with a robust kernel on registration and loop edges, whenever a submap is finished.
- A frame's online pose: its pose in its submap (from the front end) composed onto the submap's
  optimised origin, with the estimate of the moment. The final trajectory: every frame from the
  front end's smoother, with each loop the graph kept between the two frames it was seen from
  (and registration edges, see `frontend_registrations`, between the submaps' first frames);
  each submap's origin follows its first frame, so the map moves with the final trajectory.
- The global map: the optimised submaps fused into one TSDF, its iso-surface points as the
  result's cloud (the run engine writes it as map.ply), a marching-cubes mesh (mesh.ply in the run
  folder), and a 2D grid sliced between 0.2 and 1.5 m above the floor, cleared where the
  submaps' 2D rays saw through (`free_space`: the TSDF's band behind a thin wall draws it into
  the room in front).
- Poses are planar, (x, y, yaw) with z the floor's: Voxgraph's (x, y, z, yaw) on a robot that
  drives on one floor.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from longslam.core.errors import InputError
from longslam.core.frame import Frame
from longslam.core.geometry import (
    CameraMount,
    compose_xyyaw,
    invert,
    pose_from_xyyaw,
    relative_xyyaw,
    wrap_angle,
    xyyaw_from_pose,
)
from longslam.core.memory_release import release_free_memory
from longslam.core.trajectory import Trajectory
from longslam.slam import stats
from longslam.slam.api import MethodContext, MethodSpec, Result
from longslam.slam.depth_trust import trusted_depth, trusted_range
from longslam.slam.frontend import FrontEnd, MethodDepths
from longslam.slam.graph import LOOP, ODOMETRY, REGISTRATION, PoseGraph
from longslam.slam.rows import Rows
from longslam.slam.submap.config import SubmapConfig
from longslam.slam.submap.free_space import SubmapFreeSpace, carve, fuse_free_space
from longslam.slam.submap.global_map import fuse_submaps, grid_from_tsdf, write_mesh
from longslam.slam.submap.registration import RegistrationSettings, register
from longslam.slam.submap.store import SubmapStore
from longslam.slam.submap.tsdf import TSDF, depth_points

MIN_VERTICAL_NORMAL = 0.7  # |normal z| above this: floor or ceiling, useless for x, y, yaw


@dataclass
class Submap:
    index: int
    start_time: float
    tsdf: TSDF | None  # the active submap's; a finished one's is in the method's SubmapStore
    frames: int = 0
    finished: bool = False
    points: np.ndarray | None = None  # (N, 3) float32 iso-surface sample for registration
    box: tuple[np.ndarray, np.ndarray] | None = None  # 2D (min, max) corners in the submap frame
    free_space: SubmapFreeSpace | None = None  # 2D rays for the grid (grid_free_space)


@dataclass
class _Keyframe:  # a frame kept for place recognition (loop closure only)
    frame: int  # its index in the sequence
    submap: int
    in_submap: np.ndarray  # (4, 4) camera pose in its submap's frame
    features: Any


@dataclass
class _Counts:
    frames: int = 0
    frames_without_depth: int = 0
    free_space_frames: int = 0  # frames whose depth voted free space (grid_free_space_interval)
    registrations_accepted: int = 0
    registrations_rejected: int = 0
    submaps_too_few_points: int = 0
    loops_accepted: int = 0
    loops_rejected: int = 0
    # Of loops_rejected, those PnP verified and both images' depth did not hold (loop_min_depth_support).
    loops_rejected_depth: int = 0
    loop_hypotheses: int = 0
    loop_keyframes_kept: int = 0
    loop_keyframes_known_place: int = 0  # not kept: a kept one stands there (loop_keyframe_min_distance)
    rejection_reasons: dict[str, int] = field(default_factory=dict)


class SubmapMethod:
    name = "submap"

    def __init__(self, context: MethodContext, config: SubmapConfig = SubmapConfig()):
        self.config = config
        self.context = context
        c = self.config
        self.registration_settings = RegistrationSettings(
            min_points=c.registration_min_points,
            max_rms=c.registration_max_rms,
            max_translation=c.registration_max_correction,
            effective_points=c.registration_effective_points,
        )
        self.graph = PoseGraph(c.robust_kernel, c.robust_k, max_iterations=50)
        self.submaps: list[Submap] = []
        # Finished submaps' TSDFs: on disk beside the run's files, a few in memory.
        self.store = SubmapStore(c.voxel_size, c.truncation, c.submaps_in_memory, context.output_dir)
        self.counts = _Counts()
        self._mount: CameraMount | None = None  # the front end's, known at the first frame
        self.frontend = FrontEnd(context.intrinsics, c.frontend)
        # Every frame's depth goes into the TSDF; colour too when the front end reads it.
        self.images_every_frame = ("rgb", "depth") if "rgb" in self.frontend.images_every_frame else ("depth",)
        self._submap_frame: list[int] = []  # index of each submap's first frame
        self._last_odometry: np.ndarray | None = None
        self._pose_in_active = np.eye(4)  # camera pose of the latest frame in the active submap
        self._max_depth = c.max_ray_length if context.max_depth is None else min(c.max_ray_length, context.max_depth)
        # Per frame: stamp and online pose.
        self._stamps = Rows()
        self._online = Rows((4, 4))  # every frame's camera pose as step returned it
        self._tried_pairs: set[tuple[int, int]] = set()
        # Loop closure (place recognition shared with the keyframe method).
        self._keyframes: list[_Keyframe] = []
        # The same keyframes' time, submap and camera position and optical axis in their submap,
        # as arrays: a new keyframe's tests run over every kept one.
        self._keyframe_times = Rows()
        self._keyframe_submaps = Rows()
        self._keyframe_in_submap = Rows((2, 2))  # rows: the camera's x, y; its optical axis's x, y
        # Per accepted loop edge of the graph: (candidate frame, query frame, the query robot's
        # pose in the candidate robot's frame), for the front end's final smoother.
        self._frame_loops: dict[int, tuple[int, int, np.ndarray]] = {}
        self._vocabulary = None
        self._last_keyframe_time = -np.inf
        self._last_free_space_time = -np.inf
        # Each frame's points and normals to integrate, worked out ahead (`work_ahead`) until its step.
        self._ahead_points: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        if c.loops_on:
            from longslam.slam.place_recognition import Vocabulary

            self._vocabulary = Vocabulary(max_words_per_image=c.loop_max_features)

    # --- geometry helpers --------------------------------------------------------------------
    def _origin_pose(self, xyyaw: np.ndarray) -> np.ndarray:
        assert self._mount is not None  # the front end's, from the first frame on
        return pose_from_xyyaw(xyyaw, self._mount.floor_z)

    def _world_pose(self, submap: int, in_submap: np.ndarray) -> np.ndarray:
        return self._origin_pose(self.graph.estimate(submap)) @ in_submap

    # --- frames ------------------------------------------------------------------------------
    def work_ahead(self, frame: Frame) -> None:
        """On the engine's read-ahead thread, before this frame's step: the front end's part
        (`FrontEnd.work_ahead`) and the frame's points to integrate, from its trusted depth."""
        ahead = self.frontend.work_ahead(frame)
        depth = np.asarray(frame.depth)
        if not self._integrates(depth, frame):
            return
        # The depth `FrameStep.depths` gives the step: the front end's, or on wheels alone measured here.
        trusted = (
            ahead.trusted
            if ahead is not None
            else trusted_depth(depth, trusted_range(depth, self.config.frontend.depth_trust))
        )
        self._ahead_points[frame.index] = self._depth_points(trusted, frame)

    def _integrates(self, depth: np.ndarray, frame: Frame) -> bool:
        return depth.ndim == 2 and depth.shape == (frame.intrinsics.height, frame.intrinsics.width)

    def _depth_points(self, depth: np.ndarray, frame: Frame) -> tuple[np.ndarray, np.ndarray]:
        return depth_points(depth, frame.intrinsics, self.config.integration_stride, self._max_depth, with_normals=True)

    def step(self, frame: Frame) -> np.ndarray:
        motion = self.frontend.step(frame)
        odometry = self.frontend.camera_poses(motion.xyyaw[None])[0]
        self._mount = self.frontend.mount
        assert self._mount is not None  # the front end placed it at the first frame
        active = self.submaps[-1] if self.submaps else None
        if active is None:
            base = self._mount.to_planar(odometry[None])[0]
            active = self._start_submap(frame.timestamp, base)
            in_submap = invert(self._origin_pose(base)) @ odometry
        else:
            # The odometry's motion since the last frame, applied to the last pose.
            in_submap = self._pose_in_active @ (invert(self._last_odometry) @ odometry)
            if frame.timestamp - active.start_time >= self.config.submap_interval:
                # The new submap's origin: the robot's floor pose now, in the old submap's frame.
                delta = self._mount.to_planar(in_submap[None])[0]
                active = self._start_submap(frame.timestamp, delta)
                in_submap = invert(pose_from_xyyaw(delta)) @ in_submap
        self._last_odometry = odometry
        depth = np.asarray(frame.depth)
        # Integrated only where the frame's depth noise allows (the front end's rule); loop
        # features to where their noise, weighed in the verification, still places them.
        depths = motion.depths(depth) if depth.ndim == 2 else MethodDepths(depth, depth, None)
        depth, loop_depth, depth_noise = depths.trusted, depths.loops, depths.loop_noise
        updates = 0
        assert active.tsdf is not None  # the active submap holds its TSDF
        points = self._ahead_points.pop(frame.index, None)
        if self._integrates(depth, frame):
            if points is None:  # not worked out ahead
                points = self._depth_points(depth, frame)
            updates = active.tsdf.integrate_camera_points(*points, in_submap)
        if updates == 0:
            self.counts.frames_without_depth += 1
        elif active.free_space is not None and self._free_space_due(frame.timestamp):
            # For the 2D map only: nothing here feeds registration or the trajectory.
            active.free_space.add(
                depth, frame.intrinsics, self._mount.camera_in_base, self._mount.to_planar(in_submap[None])[0]
            )
            self._last_free_space_time = frame.timestamp
            self.counts.free_space_frames += 1
        active.frames += 1
        self.counts.frames += 1
        if (
            self._vocabulary is not None
            and (updates or depth_noise is not None)  # noisy depth: loops reach past what is integrated
            and frame.timestamp - self._last_keyframe_time >= self.config.loop_keyframe_interval
        ):
            self._last_keyframe_time = frame.timestamp
            self._loop_closure(
                frame, active, in_submap, loop_depth, depth_noise, depths.loop_min_inliers(self.config.loop_min_inliers)
            )
        self._pose_in_active = in_submap
        pose = self._world_pose(active.index, in_submap)
        self._stamps.append(float(frame.timestamp))
        self._online.append(pose)
        return pose

    def _free_space_due(self, time: float) -> bool:
        """Whether the frame at `time` votes free space: `grid_free_space_interval` after the last
        that did (a millisecond early counts, so that 0.2 s at 10 Hz is every second frame)."""
        return time - self._last_free_space_time >= self.config.grid_free_space_interval - 1e-3

    def _start_submap(self, time: float, origin: np.ndarray) -> Submap:
        """Start a submap at `origin`: the world pose (x, y, yaw) for the first submap, the pose in
        the previous submap's frame for the others (that is the odometry constraint)."""
        c = self.config
        index = len(self.submaps)
        self._submap_frame.append(len(self._stamps))
        if self.submaps:
            previous = self.submaps[-1]
            self._finish_submap(previous)
            self.graph.add_node(index, compose_xyyaw(self.graph.estimate(previous.index), origin))
            info = np.diag([c.odometry_xy_std**-2, c.odometry_xy_std**-2, c.odometry_sigma_yaw**-2])
            self.graph.add_edge(previous.index, index, origin, information=info, kind=ODOMETRY)
        else:
            self.graph.add_node(index, origin)
        free_space = None
        if c.grid_free_space:
            free_space = SubmapFreeSpace(
                c.grid_resolution, self._max_depth, c.grid_min_height, c.grid_max_height, c.integration_stride
            )
        submap = Submap(index, time, TSDF(c.voxel_size, c.truncation), free_space=free_space)
        self.submaps.append(submap)
        return submap

    # --- finishing a submap: compact, sample, register, optimise --------------------------------
    def _finish_submap(self, submap: Submap) -> None:
        if submap.finished:
            return
        c = self.config
        assert submap.tsdf is not None  # not finished: the TSDF is still the submap's
        points, normals = submap.tsdf.surface_points()
        assert normals is not None  # asked for (with_normals)
        bounds = submap.tsdf.bounds()
        submap.tsdf.compact()
        self.store.put(submap.index, submap.tsdf)
        submap.tsdf = None
        if submap.free_space is not None:
            submap.free_space.finish()
        submap.finished = True
        if bounds is not None:
            submap.box = (bounds[0][:2].astype(np.float64), bounds[1][:2].astype(np.float64))
        upright = np.abs(normals[:, 2]) < MIN_VERTICAL_NORMAL if len(normals) else np.zeros(0, bool)
        candidates = points[upright]
        n = min(int(np.ceil(len(candidates) * c.registration_sampling_ratio)), c.registration_max_points)
        n = max(n, min(len(candidates), c.registration_min_points))  # a small submap keeps what it has
        rng = np.random.default_rng(submap.index)
        submap.points = (
            candidates[np.sort(rng.choice(len(candidates), n, replace=False))] if n else np.zeros((0, 3), np.float32)
        )
        if len(submap.points) < c.registration_min_points:
            self.counts.submaps_too_few_points += 1
        elif c.registration:
            self._register_submap(submap)
        self.graph.optimize(warm_start=True)

    def _world_box(self, submap: Submap) -> tuple[np.ndarray, np.ndarray] | None:
        if submap.box is None:
            return None
        lo, hi = submap.box
        corners = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [lo[0], hi[1]], [hi[0], hi[1]]])
        x, y, yaw = self.graph.estimate(submap.index)
        c, s = np.cos(yaw), np.sin(yaw)
        world = np.column_stack([x + c * corners[:, 0] - s * corners[:, 1], y + s * corners[:, 0] + c * corners[:, 1]])
        return world.min(axis=0), world.max(axis=0)

    def _register_submap(self, reading: Submap) -> None:
        box = self._world_box(reading)
        if box is None:
            return
        overlapping = []
        for reference in self.submaps:
            if reference.index == reading.index or not reference.finished or reference.box is None:
                continue
            assert reference.points is not None  # a finished submap's sample
            if len(reference.points) < self.config.registration_min_points:
                continue
            other = self._world_box(reference)
            assert other is not None  # its box is known
            overlap = np.minimum(box[1], other[1]) - np.maximum(box[0], other[0])
            if np.any(overlap <= 0) or overlap.prod() < self.config.registration_min_overlap_area:
                continue
            pair = (reference.index, reading.index)
            if pair in self._tried_pairs:
                continue
            overlapping.append((float(overlap.prod()), reference))
        if self.config.registration_max_references:
            # The most overlapping few: a corridor driven for the n-th time overlaps n passes of
            # submaps, and registering against all of them made the cost grow with every lap.
            overlapping.sort(key=lambda item: -item[0])  # stable: older submaps first among equals
            overlapping = sorted(overlapping[: self.config.registration_max_references], key=lambda item: item[1].index)
        for _, reference in overlapping:
            self._tried_pairs.add((reference.index, reading.index))
            initial = relative_xyyaw(self.graph.estimate(reference.index), self.graph.estimate(reading.index))
            result = register(self.store.get(reference.index), reading.points, initial, self.registration_settings)
            if result.accepted:
                self.counts.registrations_accepted += 1
                self.graph.add_edge(
                    reference.index,
                    reading.index,
                    result.relative,
                    information=result.information,
                    kind=REGISTRATION,
                    robust=True,
                )
            else:
                self.counts.registrations_rejected += 1
                key = _reason_key(result.reason)
                self.counts.rejection_reasons[key] = self.counts.rejection_reasons.get(key, 0) + 1

    # --- loop closure ------------------------------------------------------------------------------
    def _loop_closure(
        self,
        frame: Frame,
        active: Submap,
        in_submap: np.ndarray,
        depth: np.ndarray,
        depth_noise: float | None,
        min_inliers: int,
    ) -> None:
        """Look for a loop from this frame (its `depth` for loops, of inverse-depth noise
        `depth_noise`, 1/m) to an older submap's keyframe, verified by at least `min_inliers` PnP inliers."""
        from longslam.slam import features as feature_module
        from longslam.slam.place_recognition import depth_held_transform, planar_link, verify

        c = self.config
        assert self._vocabulary is not None and self._mount is not None  # loops are on; called from `step`
        feats = feature_module.extract(frame.rgb, depth, frame.intrinsics, max_features=c.loop_max_features)
        if len(feats) == 0:
            return
        old = np.flatnonzero(
            (frame.timestamp - self._keyframe_times.array() >= c.loop_min_age)
            & (self._keyframe_submaps.array() < active.index - 1)
        )
        if len(old):
            hits = self._vocabulary.query(feats.descriptors, candidates=old, top_k=1)
            if hits and hits[0][1] >= c.loop_min_score:
                self.counts.loop_hypotheses += 1
                candidate = self._keyframes[hits[0][0]]
                check = verify(feats, candidate.features, frame.intrinsics, min_inliers=min_inliers)
                transform = None
                if check.accepted:
                    transform = depth_held_transform(
                        feats,
                        candidate.features,
                        check.transform,
                        frame.intrinsics.fx,
                        c.loop_refine_3d,
                        c.loop_min_depth_support,
                        depth_noise,
                    )
                    if transform is None:
                        self.counts.loops_rejected_depth += 1
                link = planar_link(self._mount.camera_in_base, transform) if transform is not None else None
                if link is not None:
                    self._add_loop(candidate, transform, link, active, in_submap)
                else:
                    self.counts.loops_rejected += 1
        if self._known_place(active.index, in_submap):
            self.counts.loop_keyframes_known_place += 1
            return
        node = len(self._keyframes)
        self._keyframes.append(_Keyframe(len(self._stamps), active.index, in_submap.copy(), feats))
        self._keyframe_times.append(frame.timestamp)
        self._keyframe_submaps.append(active.index)
        self._keyframe_in_submap.append((in_submap[:2, 3], in_submap[:2, 2]))
        self._vocabulary.add(node, feats.descriptors)
        self.counts.loop_keyframes_kept += 1

    def _known_place(self, submap: int, in_submap: np.ndarray) -> bool:
        """Whether a kept keyframe's camera stands within `loop_keyframe_min_distance` and
        `loop_keyframe_min_angle` of this camera (`in_submap` in `submap`), both at the graph's
        current estimates."""
        c = self.config
        if c.loop_keyframe_min_distance <= 0 or not self._keyframes:
            return False
        here = self._world_pose(submap, in_submap)
        submaps, at = np.unique(self._keyframe_submaps.array().astype(np.int64), return_inverse=True)
        origins = self.graph.estimates(submaps)[at]  # each keyframe's submap origin, x, y, yaw
        cos, sin = np.cos(origins[:, 2]), np.sin(origins[:, 2])
        rotation = np.stack([np.stack([cos, -sin], -1), np.stack([sin, cos], -1)], 1)  # (K, 2, 2)
        in_submap = self._keyframe_in_submap.array()
        # A submap's origin turns about the vertical only: the floor-plane parts suffice.
        position = np.einsum("kij,kj->ki", rotation, in_submap[:, 0]) + origins[:, :2]
        axis = np.einsum("kij,kj->ki", rotation, in_submap[:, 1])
        near = np.hypot(*(position - here[:2, 3]).T) <= c.loop_keyframe_min_distance
        # Camera headings: the optical axis (z) on the floor plane.
        turn = np.arctan2(axis[:, 1], axis[:, 0]) - np.arctan2(here[1, 2], here[0, 2])
        turned = np.abs(wrap_angle(turn)) <= c.loop_keyframe_min_angle
        return bool(np.any(near & turned))

    def _add_loop(
        self,
        candidate: _Keyframe,
        query_in_candidate: np.ndarray,
        link: np.ndarray,
        active: Submap,
        in_submap: np.ndarray,
    ) -> None:
        """`query_in_candidate`: the query camera in the candidate camera; `link`: the same as the
        query robot's planar pose in the candidate robot's frame."""
        c = self.config
        # Pose of the active submap's origin in the candidate submap's frame.
        origin = candidate.in_submap @ query_in_candidate @ invert(in_submap)
        delta = xyyaw_from_pose(origin)
        info = np.diag([c.loop_sigma_xy**-2, c.loop_sigma_xy**-2, c.loop_sigma_yaw**-2])
        check = self.graph.try_loop(
            candidate.submap, active.index, delta, information=info, max_error=c.loop_max_error, check="edge"
        )
        if check.accepted:
            self.counts.loops_accepted += 1
            assert check.edge_id is not None  # an accepted loop's edge is kept
            self._frame_loops[check.edge_id] = (candidate.frame, len(self._stamps), link)
        else:
            self.counts.loops_rejected += 1

    # --- the end ---------------------------------------------------------------------------------
    def map_bytes(self) -> dict[str, int]:
        finished = [s for s in self.submaps if s.finished]
        active = [s for s in self.submaps if not s.finished]
        out = {
            "submap_tsdfs_finished": self.store.cached_bytes,  # those in memory
            "submap_tsdfs_on_disk": self.store.stored_bytes,
            "submap_tsdf_active": int(sum(s.tsdf.nbytes for s in active if s.tsdf is not None)),
            "registration_points": int(sum(s.points.nbytes for s in finished if s.points is not None)),
            "frame_poses": int(self._stamps.nbytes + self._online.nbytes),
        }
        if spaces := [s.free_space for s in self.submaps if s.free_space is not None]:
            out["free_space"] = int(sum(f.nbytes for f in spaces))
        if self._vocabulary is not None:
            out["loop_keyframes"] = int(sum(k.features.nbytes for k in self._keyframes))
            out["vocabulary"] = int(self._vocabulary.nbytes)
        return out

    def finish(self) -> Result:
        if not self._stamps:
            raise InputError("the submap method received no frames")
        bytes_before = self.map_bytes()
        self._finish_submap(self.submaps[-1])
        c = self.config
        map_bytes = self.map_bytes()
        # Mapping is over: the place-recognition keyframes and their vocabulary go before the
        # final smoother, the finish's peak, is built.
        self._keyframes, self._vocabulary = [], None
        self._keyframe_times, self._keyframe_submaps, self._keyframe_in_submap = Rows(), Rows(), Rows((2, 2))
        release_free_memory()
        stamps = self._stamps.array()
        final = self._frontend_final()
        assert self._mount is not None  # frames were given
        poses = self._mount.to_camera(final)
        # Each submap's origin is the robot's pose at its first frame: the map moves with the
        # final trajectory.
        origins = np.array([self._origin_pose(final[self._submap_frame[s.index]]) for s in self.submaps])
        trajectory = Trajectory(stamps, poses, source="submap")
        online = Trajectory(stamps, self._online.array(), source="submap online")
        # The submaps are read back one at a time into the fused map: the run is over, and holding
        # them all beside it would be the run's peak.
        self.store.drop_cache()
        fused = fuse_submaps(lambda i: self.store.get(i, cache=False), origins, c.voxel_size, c.truncation)
        submaps_read = self.store.reads
        self.store.close()
        cloud, _ = fused.surface_points(with_normals=False)
        grid = grid_from_tsdf(
            fused, cloud, self._mount.floor_z, c.grid_min_height, c.grid_max_height, c.grid_resolution
        )
        if c.grid_free_space:
            # The submaps' rays at their final origins, as the TSDF's voxels were fused.
            free = fuse_free_space(
                (
                    (s.free_space.finish(), final[self._submap_frame[s.index]])
                    for s in self.submaps
                    if s.free_space is not None
                ),
                c.grid_resolution,
            )
            grid = carve(grid, free, c.grid_free_space_margin)
        mesh_path = None
        if c.write_mesh and self.context.output_dir:
            mesh_path = write_mesh(fused, Path(self.context.output_dir) / "mesh.ply")
        counts = self.counts
        run_stats = {
            stats.FRAMES: counts.frames,
            stats.SUBMAPS: len(self.submaps),
            stats.FRAMES_WITHOUT_DEPTH: counts.frames_without_depth,
            "free_space_frames": counts.free_space_frames,
            "submaps_too_few_points": counts.submaps_too_few_points,
            "registrations_accepted": counts.registrations_accepted,
            "registrations_rejected": counts.registrations_rejected,
            "registration_rejection_reasons": dict(counts.rejection_reasons),
            stats.LOOP_HYPOTHESES: counts.loop_hypotheses,
            stats.LOOPS_ACCEPTED: counts.loops_accepted,
            stats.LOOPS_REJECTED: counts.loops_rejected,
            "loops_rejected_depth": counts.loops_rejected_depth,
            "loop_keyframes_kept": counts.loop_keyframes_kept,
            "loop_keyframes_known_place": counts.loop_keyframes_known_place,
            "graph_edges": {k: self.graph.count(k) for k in (ODOMETRY, REGISTRATION, LOOP)},
            stats.OPTIMIZATIONS: self.graph.optimizations,
            stats.CAMERA_HEIGHT: self._mount.camera_height,
            stats.MAP_BYTES: map_bytes,
            "map_bytes_before_finish": bytes_before,
            "fused_map_bytes": fused.nbytes,
            "submaps_read_back": submaps_read,  # TSDFs read from the store (registration and fusion)
            "fused_blocks": fused.num_blocks,
            "mesh": mesh_path.name if mesh_path else None,  # in the run folder
        }
        run_stats["frontend"] = self.frontend.stats
        return Result(
            trajectory=trajectory,
            online=online,
            grid=grid,
            cloud=cloud.astype(np.float64),
            stats=run_stats,
            tables={"loops": self.frontend.loop_table(), "frontend": self.frontend.frame_table()},
        )

    def _frontend_final(self) -> np.ndarray:
        """Every frame's pose from the front end's smoother, with the submap graph's loops
        between the frames they were seen from (and registration edges, see
        `frontend_registrations`, between the submaps' first frames). An edge the optimised graph
        explains poorly (the robust kernel down-weighted it) is left out: the smoother takes each
        edge as a plain Gaussian."""
        c = self.config
        registrations = c.frontend_registrations
        if registrations is None:
            registrations = c.frontend.mode == "wheel"
        edges = [
            e
            for e in self.graph.edges
            if e.kind != ODOMETRY
            and (e.kind != REGISTRATION or registrations)
            and self.graph.edge_error(e.edge_id) <= c.frontend_max_edge_error
        ]
        # A loop fixes two frames, not two submaps: between its own frames it needs no submap to
        # be rigid, so it takes keyframe's tight sigmas.
        loop_information = np.diag([c.loop_frame_sigma_xy**-2, c.loop_frame_sigma_xy**-2, c.loop_frame_sigma_yaw**-2])
        for edge in edges:
            if edge.edge_id in self._frame_loops:
                frame_i, frame_j, link = self._frame_loops[edge.edge_id]
                self.frontend.add_loop(frame_i, frame_j, link, loop_information)
        self.frontend.add_graph_edges([e for e in edges if e.edge_id not in self._frame_loops], self._submap_frame)
        held = {
            frame: self.graph.estimate(index)
            for index, frame in enumerate(self._submap_frame)
            if self.graph.has_node(index)
        }
        return self.frontend.final_trajectory(held)


def _reason_key(reason: str) -> str:
    for key in ("overlap", "RMS", "converge", "correction", "surface points", "singular", "non-finite"):
        if key in reason:
            return key.lower().replace(" ", "_")
    return "other"


SPEC = MethodSpec("submap", SubmapConfig, SubmapMethod, "Voxgraph's design: TSDF submaps in a pose graph")
