"""Parameters of the keyframe method, defaults after RTAB-Map 0.23 and the paper's set-up."""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import ClassVar

from longslam.core.errors import InputError
from longslam.core.settings import check_limits
from longslam.slam.frontend import FrontEndConfig
from longslam.slam.place_recognition import WORD_INDEXES

# Size-like parameters held to ranges that keep a run within a machine's memory: a grid's cells
# grow as 1/cell^2 (a micrometre cell exhausts any machine's memory at the first node), and feature and
# word counts size per-node arrays. (least, most, unit and why), both ends inclusive.
SIZE_LIMITS = {
    "grid_cell": (0.01, 10.0, "m", "a finer grid needs (range / cell)^2 cells per node"),
    "cloud_voxel": (0.01, 10.0, "m", "a finer cloud keeps every depth point of every node"),
    "grid_range": (0.1, 100.0, "m", "a node's local grid spans twice this"),
    "max_features": (1, 100_000, "", "features are held per node"),
    "max_words": (1, 100_000, "", "words are held per node"),
    "stm_size": (0, 100_000, "", "short-term memory is held in RAM"),
    "loop_candidates": (1, 1000, "", "each is verified by PnP every node"),
    "proximity_candidates": (0, 1000, "", "each is verified by PnP every node"),
}


@dataclass(frozen=True)
class KeyframeConfig:
    # The values a text parameter takes (`longslam list --params` shows them).
    CHOICES: ClassVar[dict[str, tuple[str, ...]]] = {"vocabulary_index": tuple(WORD_INDEXES)}

    # Node creation (Rtabmap/DetectionRate, RGBD/LinearUpdate, RGBD/AngularUpdate).
    detection_rate: float = 1.0  # Hz: at most this many new nodes per second
    linear_update: float = 0.1  # m moved since the last node
    angular_update: float = 0.1  # rad turned since the last node
    # Features: the paper used 2000 per image; Kp/MaxFeatures keeps 500 as visual words.
    max_features: int = 2000  # ORB features detected per image
    max_words: int = 500  # features of a node kept as its visual words (Kp/MaxFeatures)
    # Hamming bits to join an existing word: ORB descriptors of one 3D point seen again mostly
    # differ by under 64 bits, unrelated ones by about 128, so 64 lets revisits share words.
    word_distance: int = 64
    # How a descriptor finds its nearest word (place_recognition.WORD_INDEXES): "bruteforce"
    # (OpenCV, exact), "flat" (faiss, exact, faster), "hnsw" (faiss, approximate, cost ~ log of
    # the dictionary's size).
    vocabulary_index: str = "hnsw"
    # Words no node in short-term or working memory holds leave the search index (RTAB-Map drops
    # them too); false: every word stays searchable.
    vocabulary_forget: bool = True
    # Memory (Mem/STMSize, Rtabmap/MemoryThr, Rtabmap/MaxRetrieved).
    stm_size: int = 10
    wm_max_nodes: int = 150  # nodes searched for loop closure; 0 = unbounded
    max_retrieved: int = 2  # long-term nodes brought back next to a loop closure, per node
    database: bool = True  # long-term memory in RUN/memory.db (needs an output folder)
    # Loop closure: appearance hypotheses verified by PnP RANSAC (Vis/MinInliers).
    loop_threshold: float = 0.15  # tf-idf cosine score a hypothesis must reach
    loop_candidates: int = 2  # best hypotheses verified per node
    min_inliers: int = 20  # PnP RANSAC inliers a loop transform needs to be accepted
    # Only points this high above the floor anchor a transform: repeating floor tiles and ceiling
    # panels let PnP lock onto a copy one tile away (seen on the demo route: a 1.3 m wrong loop).
    anchor_min_height: float = 0.15
    anchor_max_height: float = 2.6  # m: points higher than this above the floor anchor no transform
    # Polish each verified transform on 3D-3D matches (depth on both sides), as RTAB-Map's
    # Vis/EstimationType 0: PnP on one side's depth leaves a loop's transform as noisy as that depth.
    refine_3d: bool = True
    # A loop or proximity link is kept only if both images' depth hold its transform: this many
    # 3D-3D matches land within 3 pixels' footprint (at least 5 cm) of it (0: not checked): a
    # link held by one image's depth alone can lock onto a look-alike place.
    loop_min_depth_support: int = 10
    # Proximity detection (RGBD/ProximityBySpace, RGBD/LocalRadius).
    proximity: bool = True
    proximity_radius: float = 3.0  # m around the estimated pose
    proximity_max_angle: float = 0.8  # rad: only nodes that looked the same way
    proximity_candidates: int = 1  # nearby nodes verified by PnP per node (0: none)
    # Proximity by scan matching (RGBD/ProximityBySpace with ICP, scan_proximity.py): the new
    # node's obstacle cells registered against older nearby nodes' that shared open space with it,
    # whichever way they looked. None: on with the fused front end, off in "wheel" mode (the
    # paper's RTAB-Map: Reg/Strategy 0, visual proximity only).
    scan_proximity: bool | None = None
    scan_proximity_radius: float = 4.0  # m between the estimates of the new node and an older one
    scan_proximity_min_age: float = 30.0  # s: older nodes only (the front end matched the recent ones)
    scan_proximity_max_correction: float = 0.5  # m a scan link may move the new node's estimate
    scan_proximity_max_angle: float = 0.05  # rad a scan link may turn the new node's estimate
    scan_proximity_min_overlap: float = 0.5  # share of the new node's obstacle cells matched
    scan_proximity_max_rmse: float = 0.04  # m: point-to-line RMS a scan link may have
    scan_proximity_max_candidates: int = 8  # nearest older nodes registered against (0: every one in the radius)
    # Matched cells whose wall faces a direction (within 45 degrees) for a link to hold the node in
    # it; fewer, and the link leaves that direction free (along a straight corridor). 0: trust the
    # registration's Hessian in every direction.
    scan_proximity_min_constraining: int = 10
    # Graph (RGBD/OptimizeMaxError): a new loop whose error exceeds this is rejected.
    optimize_max_error: float = 3.0  # sigmas: a new loop whose error after optimisation exceeds this is rejected
    odom_sigma_linear: float = 0.05  # odometry link std per metre travelled
    # Wheels barely slip sideways: drift is forward scale and heading, so a link's lateral std is
    # a fraction of its forward std, and the graph explains drift by turning rather than sliding.
    odom_sigma_lateral: float = 0.2
    odom_sigma_angular: float = 0.005  # odometry link yaw std per second (rad/s)
    odom_sigma_min: float = 0.01  # floor of a link's std (m, rad)
    loop_sigma_linear: float = 0.05  # m: std of a loop-closure link's translation
    loop_sigma_angular: float = 0.02  # rad: std of a loop-closure link's rotation
    # Maps (Grid/CellSize, Grid/RangeMax, obstacle band from the paper).
    grid_cell: float = 0.05
    # RTAB-Map's Grid/RangeMax is 5 m; the grid takes the camera's whole range instead (8 m in
    # the paper's setup), so that every wall the camera saw is in the map.
    grid_range: float = 8.0
    grid_stride: int = 1  # pixel stride of the depth points a node's local grid is built from
    obstacle_min_height: float = 0.2  # m above the floor: lower depth points are floor, not obstacles
    obstacle_max_height: float = 1.5  # m above the floor: higher depth points are left out of the grid
    cloud_voxel: float = 0.05  # m: voxel size of the 3D map's point cloud
    cloud_stride: int = 8  # pixel stride of the depth points kept per node for the 3D map
    # Where each frame's motion comes from (longslam.slam.frontend), every field a parameter
    # (`frontend.mode=wheel`, `frontend.camera_height=1.3`...): mode "fused" (wheels with their
    # biases estimated, scan-to-map and gated RGB-D steps; runs without odometry.txt) or "wheel"
    # (the wheel odometry alone: the paper's configuration). Either way the final trajectory
    # comes from the front end's smoother over every frame, with the graph's loop closures.
    frontend: FrontEndConfig = field(default_factory=FrontEndConfig)

    @property
    def scan_proximity_on(self) -> bool:
        """Whether proximity is tried by scan matching (`scan_proximity`, or by the front end's mode when unset)."""
        return self.frontend.mode == "fused" if self.scan_proximity is None else self.scan_proximity

    def __post_init__(self) -> None:
        positive = (
            "detection_rate",
            "max_features",
            "max_words",
            "min_inliers",
            "grid_cell",
            "grid_range",
            "odom_sigma_min",
            "loop_sigma_linear",
            "loop_sigma_angular",
            "optimize_max_error",
            "scan_proximity_radius",
            "scan_proximity_max_correction",
            "scan_proximity_max_angle",
            "scan_proximity_min_overlap",
            "scan_proximity_max_rmse",
            "cloud_voxel",
            "cloud_stride",
            "grid_stride",
            "loop_candidates",
        )
        for name in positive:
            if not getattr(self, name) > 0:
                raise InputError(f"method 'keyframe': parameter {name} must be positive, got {getattr(self, name)}")
        for name in (f.name for f in fields(self)):
            value = getattr(self, name)
            if isinstance(value, (int, float)) and not isinstance(value, bool) and value < 0:
                raise InputError(f"method 'keyframe': parameter {name} must not be negative, got {value}")
        check_limits(self, SIZE_LIMITS, "method 'keyframe'")
        if self.vocabulary_index not in WORD_INDEXES:
            raise InputError(
                f"method 'keyframe': parameter vocabulary_index must be one of {', '.join(WORD_INDEXES)}, "
                f"got {self.vocabulary_index!r}"
            )
        if self.obstacle_max_height <= self.obstacle_min_height:
            raise InputError("method 'keyframe': obstacle_max_height must exceed obstacle_min_height")
