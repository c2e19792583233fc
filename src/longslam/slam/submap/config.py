"""The submap method's parameters: one typed config, the paper's / Voxgraph's values as defaults.

Every field can be set from the command line (`longslam run --method submap --param voxel_size=0.1`)
or a study file, through `longslam.core.settings.from_mapping`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

from longslam.core.errors import InputError
from longslam.core.settings import check_limits
from longslam.slam.frontend import FrontEndConfig

# Size-like parameters held to ranges that keep a run within a machine's memory: a TSDF's voxels
# near the surface grow as truncation / voxel_size^3, a grid's cells as 1/resolution^2.
# (least, most, unit and why), both ends inclusive.
SIZE_LIMITS = {
    "voxel_size": (0.02, 5.0, "m", "a TSDF holds (truncation / voxel_size) voxels across each surface"),
    "grid_resolution": (0.01, 10.0, "m", "the grid holds (extent / resolution)^2 cells"),
    "max_ray_length": (0.1, 100.0, "m", "every ray is integrated up to this range"),
    "registration_max_points": (1, 1_000_000, "", "points are matched between every pair of submaps"),
    "loop_max_features": (1, 100_000, "", "features are held per keyframe"),
}
ROBUST_KERNELS = ("cauchy", "huber", "none")
MAX_TRUNCATION_VOXELS = 40  # truncation / voxel_size: voxels on each side of a surface


@dataclass(frozen=True)
class SubmapConfig:
    # The values a text parameter takes (`longslam list --params` shows them).
    CHOICES: ClassVar[dict[str, tuple[str, ...]]] = {"robust_kernel": ROBUST_KERNELS}

    # TSDF (the paper: voxel 0.2 m, truncation 0.8 m; Voxgraph: max_ray_length_m 16)
    voxel_size: float = 0.2
    truncation: float = 0.8  # m: TSDF truncation distance on each side of a surface
    max_ray_length: float = 16.0  # m: depth is integrated up to this range
    integration_stride: int = 2  # every n-th pixel in each direction (a 0.1 m footprint at 8 m)
    # Submaps (the paper and Voxgraph: a new submap every 20 s)
    submap_interval: float = 20.0
    # Finished submaps' TSDFs held in memory (the most recently used); the others wait on disk
    # (store.py) until registration or the global map needs them: memory stays flat with the route.
    submaps_in_memory: int = 8
    # Where each frame's motion comes from (longslam.slam.frontend), every field a parameter
    # (`frontend.mode=wheel`, `frontend.camera_height=1.3`...): mode "fused" (wheels with their
    # biases estimated, scan-to-map and gated RGB-D steps; runs without odometry.txt) or "wheel"
    # (the wheel odometry alone: the paper's configuration). Either way the final trajectory comes
    # from the front end's smoother over every frame, with the submap graph's edges between the
    # submaps' first frames.
    frontend: FrontEndConfig = field(default_factory=FrontEndConfig)
    frontend_max_edge_error: float = 3.0  # sigmas: graph edges beyond this stay out of the smoother
    # Registration edges into the front end's smoother (loop edges always go). None: only in
    # "wheel" mode, where they are the only correction the smoother gets. Off in "fused" mode: a
    # submap of 20 s carries its own drift, so a registration edge can be off by more than the
    # front end's own estimate while its graph error stays small, and the scan-to-map factors
    # already hold the local geometry.
    frontend_registrations: bool | None = None
    # Registration constraints between finished submaps whose bounding boxes overlap
    registration: bool = True
    registration_sampling_ratio: float = 0.5  # share of the upright iso-surface points used (see README)
    registration_min_points: int = 100  # iso-surface points a submap needs to be registered
    registration_max_points: int = 1500  # most iso-surface points matched per submap pair
    registration_max_rms: float = 0.15  # metres (submaps built on drifting odometry are not rigid)
    registration_min_overlap_area: float = 4.0  # square metres of bounding-box overlap
    registration_max_references: int = 8  # most overlapping finished submaps a new one is registered to (0: all)
    registration_max_correction: float = 2.0  # metres; a larger jump is taken as a wrong minimum
    registration_effective_points: float = 20.0  # scales the constraint's information
    # Odometry constraints between consecutive submaps (Voxgraph: information x, y 1; yaw 2500)
    odometry_sigma_xy: float = 1.0
    odometry_sigma_yaw: float = 0.02  # rad: std of the heading of an odometry constraint
    # Robust kernel on registration and loop-closure constraints
    robust_kernel: str = "cauchy"
    robust_k: float = 2.0  # width of the robust kernel, in stds
    # Loop closure from visual place recognition. None: on with the fused front end, off in
    # "wheel" mode (the paper's main runs: Voxgraph has no loop closure of its own): without it
    # the fused front end's drift over a kilometre stays in the map.
    loop_closure: bool | None = None
    loop_keyframe_interval: float = 2.0  # seconds between keyframes kept for place recognition
    loop_max_features: int = 500  # ORB features kept per place-recognition keyframe
    loop_min_score: float = 0.15  # bag-of-words score a loop candidate must reach
    loop_min_inliers: int = 20  # PnP RANSAC inliers a loop closure needs
    loop_min_age: float = 30.0  # seconds: candidates must be at least this much older
    loop_sigma_xy: float = 0.5  # a closure fixes two frames, but a submap built on drifting odometry is not rigid
    loop_sigma_yaw: float = 0.05  # rad: std of a loop closure's heading
    # The same closure in the front end's final smoother, between the two frames it was seen
    # from rather than the submaps' first frames, so no submap's rigidity is assumed: keyframe's
    # loop sigmas (RTAB-Map's).
    loop_frame_sigma_xy: float = 0.05  # m: std of a loop's translation between its two frames
    loop_frame_sigma_yaw: float = 0.02  # rad: std of a loop's heading between its two frames
    loop_refine_3d: bool = True  # polish PnP's transform on the 3D-3D matches (keyframe's refine_3d)
    # 3D-3D matches that must hold a loop (keyframe's loop_min_depth_support; 0: not checked).
    loop_min_depth_support: int = 10
    loop_max_error: float = 3.0  # reject a closure whose error after optimisation exceeds this (sigmas)
    # On a route that drives the same corridors again, place-recognition keyframes and their words
    # stop growing: a keyframe is kept only where no kept one stands, so their memory follows the
    # building's size, not the route's length (0 keeps every keyframe).
    # Metres between camera positions at the graph's estimates (0: keep every keyframe).
    loop_keyframe_min_distance: float = 1.5
    loop_keyframe_min_angle: float = 0.5  # rad between camera headings for a kept keyframe to stand there
    # The 2D map sliced from the fused TSDF
    grid_min_height: float = 0.2
    grid_max_height: float = 1.5  # m above the floor: the top of the slice the 2D map is cut from
    grid_resolution: float = 0.1  # m: cell size of the 2D map
    # Clear the 2D map's cells the camera saw through, by 2D rays from each frame's depth kept per
    # submap (free_space.py): the TSDF's band behind a thin wall otherwise draws it 0.2-0.7 m into the room in front.
    grid_free_space: bool = True
    # Cells (of the grid) around a cell the rays ended on that they never clear: the wall's face, and the
    # TSDF's wall where submaps placed a little apart saw it at different places.
    grid_free_space_margin: int = 1
    write_mesh: bool = True  # map.ply mesh (marching cubes) in the run folder, if there is one

    @property
    def loops_on(self) -> bool:
        """Whether this run closes loops (`loop_closure`, or by the front end's mode when unset)."""
        return self.frontend.mode == "fused" if self.loop_closure is None else self.loop_closure

    def __post_init__(self) -> None:
        positive = [
            "voxel_size",
            "truncation",
            "max_ray_length",
            "integration_stride",
            "submap_interval",
            "registration_sampling_ratio",
            "registration_min_points",
            "registration_max_points",
            "registration_max_rms",
            "registration_max_correction",
            "registration_effective_points",
            "odometry_sigma_xy",
            "odometry_sigma_yaw",
            "robust_k",
            "loop_keyframe_interval",
            "loop_max_features",
            "loop_min_inliers",
            "loop_sigma_xy",
            "loop_sigma_yaw",
            "loop_frame_sigma_xy",
            "loop_frame_sigma_yaw",
            "loop_max_error",
            "grid_resolution",
        ]
        for name in positive:
            value = getattr(self, name)
            if not math.isfinite(value) or value <= 0:
                raise InputError(f"submap parameter {name} must be positive, got {value!r}")
        for name in ("submaps_in_memory", "registration_max_references", "loop_min_depth_support"):
            if getattr(self, name) < 0:
                raise InputError(f"submap parameter {name} must be >= 0, got {getattr(self, name)!r}")
        if self.grid_free_space_margin < 0:
            raise InputError(
                f"submap parameter grid_free_space_margin must be >= 0, got {self.grid_free_space_margin!r}"
            )
        for name in (
            "registration_min_overlap_area",
            "loop_min_score",
            "loop_min_age",
            "loop_keyframe_min_distance",
            "loop_keyframe_min_angle",
        ):
            value = getattr(self, name)
            if not math.isfinite(value) or value < 0:
                raise InputError(f"submap parameter {name} must be >= 0, got {value!r}")
        check_limits(self, SIZE_LIMITS, "method 'submap'")
        if self.truncation > MAX_TRUNCATION_VOXELS * self.voxel_size:
            raise InputError(
                f"truncation ({self.truncation:g}) may be at most {MAX_TRUNCATION_VOXELS} x voxel_size "
                f"({MAX_TRUNCATION_VOXELS * self.voxel_size:g} m): each surface holds that many voxels across"
            )
        if self.truncation <= self.voxel_size:
            raise InputError(f"truncation ({self.truncation}) must exceed voxel_size ({self.voxel_size})")
        if self.registration_sampling_ratio > 1:
            raise InputError(f"registration_sampling_ratio must be in (0, 1], got {self.registration_sampling_ratio}")
        if self.robust_kernel not in ROBUST_KERNELS:
            raise InputError(f"robust_kernel must be cauchy, huber or none, got {self.robust_kernel!r}")
        if self.grid_max_height <= self.grid_min_height:
            raise InputError("grid_max_height must exceed grid_min_height")
