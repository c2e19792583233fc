"""Parameters of the keyframe method, defaults after RTAB-Map 0.23 and the paper's set-up."""

from __future__ import annotations

from dataclasses import dataclass

from longslam.core.errors import InputError
from longslam.core.parameter import check_declared, nested, param
from longslam.slam.frontend import FrontEndConfig
from longslam.slam.place_recognition import WORD_INDEXES

# rad: the floor of an odometry link's heading std with the fused front end; tuned on
# paper-1km-x3 large seeds 1 and 2, which no page reports, and checked on the held-out set
# (docs/scale.md)
FUSED_ODOM_SIGMA_MIN_ANGULAR = 0.001


@dataclass(frozen=True)
class KeyframeConfig:
    # Node creation (Rtabmap/DetectionRate, RGBD/LinearUpdate, RGBD/AngularUpdate).
    detection_rate: float = param(1.0, "at most this many new nodes per second", above=0, unit="Hz")
    linear_update: float = param(0.1, "distance moved since the last node for a new one", at_least=0, unit="m")
    angular_update: float = param(0.1, "angle turned since the last node for a new one", at_least=0, unit="rad")
    # Features: the paper used 2000 per image; Kp/MaxFeatures keeps 500 as visual words.
    max_features: int = param(
        2000, "ORB features detected per image", at_least=1, at_most=100_000, why="features are held per node"
    )
    max_words: int = param(
        500,
        "features of a node kept as its visual words (Kp/MaxFeatures)",
        at_least=1,
        at_most=100_000,
        why="words are held per node",
    )
    # ORB descriptors of one 3D point seen again mostly differ by under 64 bits, unrelated ones by
    # about 128, so 64 lets revisits share words.
    word_distance: int = param(64, "Hamming bits within which a descriptor joins an existing word", at_least=0)
    vocabulary_index: str = param(
        "hnsw",
        "how a descriptor finds its nearest word: bruteforce (OpenCV, exact), flat (faiss, exact), hnsw (approximate)",
        choices=tuple(WORD_INDEXES),
    )
    vocabulary_forget: bool = param(
        True, "words no node in short-term or working memory holds leave the search index (as in RTAB-Map)"
    )
    # Memory (Mem/STMSize, Rtabmap/MemoryThr, Rtabmap/MaxRetrieved).
    stm_size: int = param(
        10,
        "nodes in short-term memory (Mem/STMSize), not searched for loops",
        at_least=0,
        at_most=100_000,
        why="short-term memory is held in RAM",
    )
    wm_max_nodes: int = param(150, "nodes searched for loop closure; 0 = unbounded", at_least=0)
    max_retrieved: int = param(2, "long-term nodes brought back next to a loop closure, per node", at_least=0)
    database: bool = param(True, "long-term memory in RUN/memory.db (needs an output folder)")
    # Loop closure: appearance hypotheses verified by PnP RANSAC (Vis/MinInliers).
    loop_threshold: float = param(0.15, "tf-idf cosine score a hypothesis must reach", at_least=0)
    loop_candidates: int = param(
        2, "best hypotheses verified per node", at_least=1, at_most=1000, why="each is verified by PnP every node"
    )
    min_inliers: int = param(20, "PnP RANSAC inliers a loop transform needs to be accepted", above=0)
    # Repeating floor tiles and ceiling panels let PnP lock onto a copy one tile away.
    anchor_min_height: float = param(
        0.15, "only points this high above the floor anchor a transform", at_least=0, unit="m"
    )
    anchor_max_height: float = param(
        2.6, "points higher than this above the floor anchor no transform", at_least=0, unit="m"
    )
    # PnP on one side's depth leaves a loop's transform as noisy as that depth.
    refine_3d: bool = param(
        True, "polish each verified transform on 3D-3D matches (depth on both sides), as Vis/EstimationType 0"
    )
    # A link held by one image's depth alone can lock onto a look-alike place.
    loop_min_depth_support: int = param(
        10,
        "3D-3D matches within 3 pixels' footprint (at least 5 cm) of a loop or proximity link; 0: not checked",
        at_least=0,
    )
    # Proximity detection (RGBD/ProximityBySpace, RGBD/LocalRadius).
    proximity: bool = param(True, "proximity detection: nearby nodes verified by PnP")
    proximity_radius: float = param(3.0, "radius around the estimated pose for proximity", at_least=0, unit="m")
    proximity_max_angle: float = param(0.8, "only nodes that looked the same way", at_least=0, unit="rad")
    proximity_candidates: int = param(
        1,
        "nearby nodes verified by PnP per node (0: none)",
        at_least=0,
        at_most=1000,
        why="each is verified by PnP every node",
    )
    # The new node's obstacle cells registered against older nearby nodes' that shared open space
    # with it, whichever way they looked (RGBD/ProximityBySpace with ICP, scan_proximity.py).
    scan_proximity: bool | None = param(
        None, "proximity by scan matching; none: on with the fused front end, off in wheel mode (the paper's)"
    )
    scan_proximity_radius: float = param(
        4.0, "distance between the estimates of the new node and an older one", above=0, unit="m"
    )
    scan_proximity_min_age: float = param(
        30.0, "older nodes only (the front end matched the recent ones)", at_least=0, unit="s"
    )
    scan_proximity_max_correction: float = param(
        0.5, "how far a scan link may move the new node's estimate", above=0, unit="m"
    )
    scan_proximity_max_angle: float = param(
        0.05, "how far a scan link may turn the new node's estimate", above=0, unit="rad"
    )
    scan_proximity_min_overlap: float = param(0.5, "share of the new node's obstacle cells matched", above=0)
    scan_proximity_max_rmse: float = param(0.04, "point-to-line RMS a scan link may have", above=0, unit="m")
    scan_proximity_max_candidates: int = param(
        8, "nearest older nodes registered against (0: every one in the radius)", at_least=0
    )
    # Fewer, and the link leaves that direction free (along a straight corridor).
    scan_proximity_min_constraining: int = param(
        10,
        "matched cells facing a direction (within 45 degrees) for a link to hold the node in it; 0: trust the Hessian",
        at_least=0,
    )
    # Graph (RGBD/OptimizeMaxError).
    optimize_max_error: float = param(
        3.0, "a new loop whose error after optimisation exceeds this is rejected", above=0, unit="sigmas"
    )
    odom_sigma_linear: float = param(0.05, "odometry link std per metre travelled", at_least=0)
    # Wheels barely slip sideways: drift is forward scale and heading, so the graph explains drift
    # by turning rather than sliding.
    odom_sigma_lateral: float = param(0.2, "odometry link lateral std, a fraction of its forward std", at_least=0)
    odom_sigma_angular: float = param(0.005, "odometry link yaw std per second", at_least=0, unit="rad/s")
    odom_sigma_min: float = param(
        0.01, "floor of a link's std (m; the heading's in rad too unless odom_sigma_min_angular says)", above=0
    )
    # A node a second after the last has turned by 0.005 rad of std at odom_sigma_angular, under
    # odom_sigma_min's 0.01 rad, which suits wheels alone. The fused front end's heading over a
    # second is better than that, and held at 0.01 the loops bend the graph's headings, which a
    # route longer than the front end's `smoother.hold_nodes_beyond` keeps. The translation keeps
    # its floor: at 0.001 it also sets a node's position where the robot turns on the spot, and
    # that made short routes at small noise worse.
    odom_sigma_min_angular: float | None = param(
        None,
        f"floor of a link's heading std; none: odom_sigma_min in wheel mode, {FUSED_ODOM_SIGMA_MIN_ANGULAR:g} "
        "with the fused front end",
        above=0,
        unit="rad",
    )
    loop_sigma_linear: float = param(0.05, "std of a loop-closure link's translation", above=0, unit="m")
    loop_sigma_angular: float = param(0.02, "std of a loop-closure link's rotation", above=0, unit="rad")
    # Maps (Grid/CellSize, Grid/RangeMax, obstacle band from the paper). A grid's cells grow as
    # 1/cell^2: a micrometre cell exhausts any machine's memory at the first node.
    grid_cell: float = param(
        0.05,
        "cell size of the occupancy grid (Grid/CellSize)",
        at_least=0.01,
        at_most=10.0,
        unit="m",
        why="a finer grid needs (range / cell)^2 cells per node",
    )
    # RTAB-Map's Grid/RangeMax is 5 m; the camera's whole range puts every wall it saw in the map.
    grid_range: float = param(
        8.0,
        "depth range a node's local grid is built from (Grid/RangeMax)",
        at_least=0.1,
        at_most=100.0,
        unit="m",
        why="a node's local grid spans twice this",
    )
    grid_stride: int = param(1, "pixel stride of the depth points a node's local grid is built from", above=0)
    obstacle_min_height: float = param(
        0.2,
        "height above the floor below which depth points are floor (below obstacle_max_height)",
        at_least=0,
        unit="m",
    )
    obstacle_max_height: float = param(
        1.5, "height above the floor above which depth points are left out of the grid", above=0, unit="m"
    )
    cloud_voxel: float = param(
        0.05,
        "voxel size of the 3D map's point cloud",
        at_least=0.01,
        at_most=10.0,
        unit="m",
        why="a finer cloud keeps every depth point of every node",
    )
    cloud_stride: int = param(8, "pixel stride of the depth points kept per node for the 3D map", above=0)
    # Either way the final trajectory comes from the front end's smoother over every frame, with
    # the graph's loop closures.
    frontend: FrontEndConfig = nested(
        FrontEndConfig, "where each frame's motion comes from: fused (wheels, scans, RGB-D) or wheel (the paper's)"
    )

    @property
    def odom_heading_floor(self) -> float:
        """The floor (rad) of an odometry link's heading std (`odom_sigma_min_angular`, or by the front
        end's mode when unset)."""
        if self.odom_sigma_min_angular is not None:
            return self.odom_sigma_min_angular
        return FUSED_ODOM_SIGMA_MIN_ANGULAR if self.frontend.mode == "fused" else self.odom_sigma_min

    @property
    def scan_proximity_on(self) -> bool:
        """Whether proximity is tried by scan matching (`scan_proximity`, or by the front end's mode when unset)."""
        return self.frontend.mode == "fused" if self.scan_proximity is None else self.scan_proximity

    def __post_init__(self) -> None:
        check_declared(self, "method 'keyframe'")
        if self.obstacle_max_height <= self.obstacle_min_height:
            raise InputError("method 'keyframe': obstacle_max_height must exceed obstacle_min_height")
