"""The submap method's parameters: one typed config, the paper's / Voxgraph's values as defaults.

Every field can be set from the command line (`longslam run --method submap --param voxel_size=0.1`)
or a study file, through `longslam.core.settings.from_mapping`.
"""

from __future__ import annotations

from dataclasses import dataclass

from longslam.core.errors import InputError
from longslam.core.parameter import check_declared, nested, param
from longslam.slam.frontend import FrontEndConfig

ROBUST_KERNELS = ("cauchy", "huber", "none")
MAX_TRUNCATION_VOXELS = 40  # truncation / voxel_size: voxels on each side of a surface
VOXGRAPH_ODOMETRY_SIGMA_XY = 1.0  # m, Voxgraph's odometry information 1 in x and y
FUSED_ODOMETRY_SIGMA_XY = 0.1  # m, checked on paper-1km-x3 large seeds 1 and 2, which no page reports (docs/scale.md)


@dataclass(frozen=True)
class SubmapConfig:
    # TSDF (the paper: voxel 0.2 m, truncation 0.8 m; Voxgraph: max_ray_length_m 16). A TSDF's
    # voxels near the surface grow as truncation / voxel_size^3.
    voxel_size: float = param(
        0.2,
        "TSDF voxel size",
        at_least=0.02,
        at_most=5.0,
        unit="m",
        why="a TSDF holds (truncation / voxel_size) voxels across each surface",
    )
    truncation: float = param(
        0.8, "TSDF truncation distance on each side of a surface (above voxel_size)", above=0, unit="m"
    )
    max_ray_length: float = param(
        16.0,
        "depth is integrated up to this range",
        at_least=0.1,
        at_most=100.0,
        unit="m",
        why="every ray is integrated up to this range",
    )
    integration_stride: int = param(2, "every n-th pixel in each direction (a 0.1 m footprint at 8 m)", above=0)
    submap_interval: float = param(20.0, "time between new submaps (the paper and Voxgraph: 20 s)", above=0, unit="s")
    # The others wait on disk (store.py) until registration or the global map needs them: memory
    # stays flat with the route.
    submaps_in_memory: int = param(8, "finished submaps' TSDFs held in memory (the most recently used)", at_least=0)
    # Either way the final trajectory comes from the front end's smoother over every frame, with
    # the submap graph's edges between the submaps' first frames.
    frontend: FrontEndConfig = nested(
        FrontEndConfig, "where each frame's motion comes from: fused (wheels, scans, RGB-D) or wheel (the paper's)"
    )
    frontend_max_edge_error: float = param(
        3.0, "graph edges beyond this error stay out of the front end's smoother", above=0, unit="sigmas"
    )
    # Off in "fused" mode: a submap of 20 s carries its own drift, so a registration edge can be
    # off by more than the front end's own estimate while its graph error stays small, and the
    # scan-to-map factors already hold the local geometry.
    frontend_registrations: bool | None = param(
        None, "registration edges into the front end's smoother (loop edges always go); none: only in wheel mode"
    )
    registration: bool = param(True, "registration constraints between finished submaps whose bounding boxes overlap")
    registration_sampling_ratio: float = param(
        0.5, "share of the upright iso-surface points used (see README)", above=0, at_most=1
    )
    registration_min_points: int = param(100, "iso-surface points a submap needs to be registered", above=0)
    registration_max_points: int = param(
        1500,
        "most iso-surface points matched per submap pair",
        at_least=1,
        at_most=1_000_000,
        why="points are matched between every pair of submaps",
    )
    registration_max_rms: float = param(
        0.15, "RMS a registration may have (submaps built on drifting odometry are not rigid)", above=0, unit="m"
    )
    registration_min_overlap_area: float = param(
        4.0, "bounding-box overlap for a pair to be registered", at_least=0, unit="m^2"
    )
    registration_max_references: int = param(
        8, "most overlapping finished submaps a new one is registered to (0: all)", at_least=0
    )
    registration_max_correction: float = param(
        2.0, "a larger registration jump is taken as a wrong minimum", above=0, unit="m"
    )
    registration_effective_points: float = param(20.0, "scales the registration constraint's information", above=0)
    # Odometry constraints between consecutive submaps (Voxgraph: information x, y 1; yaw 2500).
    # Voxgraph's 1 m fits wheels alone. The fused front end's motion over a submap is good to
    # centimetres, and at 1 m one registration that slid along a corridor carried a stretch of the
    # graph with it, which a route longer than the front end's `smoother.hold_nodes_beyond` keeps:
    # paper-1km-x3 large, seed 1 0.488 m, seed 0 0.810 (docs/scale.md).
    odometry_sigma_xy: float | None = param(
        None,
        "std of the position of an odometry constraint; none: 1 m in wheel mode (Voxgraph's), "
        f"{FUSED_ODOMETRY_SIGMA_XY:g} m with the fused front end",
        above=0,
        unit="m",
    )
    odometry_sigma_yaw: float = param(0.02, "std of the heading of an odometry constraint", above=0, unit="rad")
    robust_kernel: str = param(
        "cauchy", "robust kernel on registration and loop-closure constraints", choices=ROBUST_KERNELS
    )
    robust_k: float = param(2.0, "width of the robust kernel, in stds", above=0)
    # Voxgraph has no loop closure of its own; without it the fused front end's drift over a
    # kilometre stays in the map.
    loop_closure: bool | None = param(
        None, "loop closure from visual place recognition; none: on with the fused front end, off in wheel mode"
    )
    loop_keyframe_interval: float = param(2.0, "time between keyframes kept for place recognition", above=0, unit="s")
    loop_max_features: int = param(
        500,
        "ORB features kept per place-recognition keyframe",
        at_least=1,
        at_most=100_000,
        why="features are held per keyframe",
    )
    loop_min_score: float = param(0.15, "bag-of-words score a loop candidate must reach", at_least=0)
    loop_min_inliers: int = param(20, "PnP RANSAC inliers a loop closure needs", above=0)
    loop_min_age: float = param(30.0, "candidates must be at least this much older", at_least=0, unit="s")
    # A closure fixes two frames, but a submap built on drifting odometry is not rigid.
    loop_sigma_xy: float = param(0.5, "std of a loop closure's position between submaps", above=0, unit="m")
    loop_sigma_yaw: float = param(0.05, "std of a loop closure's heading", above=0, unit="rad")
    # The same closure in the front end's final smoother, between the two frames it was seen
    # from rather than the submaps' first frames, so no submap's rigidity is assumed: keyframe's
    # loop sigmas (RTAB-Map's).
    loop_frame_sigma_xy: float = param(0.05, "std of a loop's translation between its two frames", above=0, unit="m")
    loop_frame_sigma_yaw: float = param(0.02, "std of a loop's heading between its two frames", above=0, unit="rad")
    loop_refine_3d: bool = param(True, "polish PnP's transform on the 3D-3D matches (keyframe's refine_3d)")
    loop_min_depth_support: int = param(
        10, "3D-3D matches that must hold a loop (keyframe's loop_min_depth_support; 0: not checked)", at_least=0
    )
    loop_max_error: float = param(
        3.0, "reject a closure whose error after optimisation exceeds this", above=0, unit="sigmas"
    )
    # A keyframe is kept only where no kept one stands, so on a route that drives the same
    # corridors again their memory follows the building's size, not the route's length.
    loop_keyframe_min_distance: float = param(
        1.5, "distance between camera positions for a kept keyframe (0: keep every keyframe)", at_least=0, unit="m"
    )
    loop_keyframe_min_angle: float = param(
        0.5, "angle between camera headings for a kept keyframe to stand there", at_least=0, unit="rad"
    )
    # The 2D map sliced from the fused TSDF; a grid's cells grow as 1/resolution^2.
    grid_min_height: float = param(
        0.2, "height above the floor of the bottom of the 2D map's slice (below grid_max_height)", unit="m"
    )
    grid_max_height: float = param(1.5, "height above the floor of the top of the 2D map's slice", unit="m")
    grid_resolution: float = param(
        0.1,
        "cell size of the 2D map",
        at_least=0.01,
        at_most=10.0,
        unit="m",
        why="the grid holds (extent / resolution)^2 cells",
    )
    # The TSDF's band behind a thin wall otherwise draws it 0.2-0.7 m into the room in front.
    grid_free_space: bool = param(
        True, "clear the 2D map's cells the camera saw through, by 2D rays from frames' depth (free_space.py)"
    )
    # The wall's face, and the TSDF's wall where submaps placed a little apart saw it at different places.
    grid_free_space_margin: int = param(1, "cells around a cell the rays ended on that they never clear", at_least=0)
    # Frames 0.1 s apart see nearly the same floor; RTAB-Map, too, makes a grid per node, not per frame.
    grid_free_space_interval: float = param(
        0.2, "frame time between frames whose rays vote free space (0: every frame)", at_least=0, unit="s"
    )
    write_mesh: bool = param(True, "map.ply mesh (marching cubes) in the run folder, if there is one")

    @property
    def odometry_xy_std(self) -> float:
        """The std (m) of an odometry constraint's position (`odometry_sigma_xy`, or by the front
        end's mode when unset)."""
        if self.odometry_sigma_xy is not None:
            return self.odometry_sigma_xy
        return FUSED_ODOMETRY_SIGMA_XY if self.frontend.mode == "fused" else VOXGRAPH_ODOMETRY_SIGMA_XY

    @property
    def loops_on(self) -> bool:
        """Whether this run closes loops (`loop_closure`, or by the front end's mode when unset)."""
        return self.frontend.mode == "fused" if self.loop_closure is None else self.loop_closure

    def __post_init__(self) -> None:
        check_declared(self, "method 'submap'")
        if self.truncation > MAX_TRUNCATION_VOXELS * self.voxel_size:
            raise InputError(
                f"truncation ({self.truncation:g}) may be at most {MAX_TRUNCATION_VOXELS} x voxel_size "
                f"({MAX_TRUNCATION_VOXELS * self.voxel_size:g} m): each surface holds that many voxels across"
            )
        if self.truncation <= self.voxel_size:
            raise InputError(f"truncation ({self.truncation}) must exceed voxel_size ({self.voxel_size})")
        if self.grid_max_height <= self.grid_min_height:
            raise InputError("grid_max_height must exceed grid_min_height")
