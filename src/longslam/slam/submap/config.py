"""The submap method's parameters: one typed config, the paper's / Voxgraph's values as defaults.

Every field can be set from the command line: `longslam run --method submap --param voxel_size=0.1`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

from longslam.errors import InputError


@dataclass(frozen=True)
class SubmapConfig:
    # TSDF (the paper: voxel 0.2 m, truncation 0.8 m; Voxgraph: max_ray_length_m 16)
    voxel_size: float = 0.2
    truncation: float = 0.8
    max_ray_length: float = 16.0
    integration_stride: int = 2  # every n-th pixel in each direction (a 0.1 m footprint at 8 m)
    # Submaps (the paper and Voxgraph: a new submap every 20 s)
    submap_interval: float = 20.0
    # Camera height above the floor; 0 = the first odometry pose's z (the floor is at z = 0)
    camera_height: float = 0.0
    # Registration constraints between finished submaps whose bounding boxes overlap
    registration: bool = True
    registration_sampling_ratio: float = 0.5  # share of the upright iso-surface points used (see README)
    registration_min_points: int = 100
    registration_max_points: int = 1500
    registration_max_rms: float = 0.15  # metres (submaps built on drifting odometry are not rigid)
    registration_min_overlap_area: float = 4.0  # square metres of bounding-box overlap
    registration_max_correction: float = 2.0  # metres; a larger jump is taken as a wrong minimum
    registration_effective_points: float = 20.0  # scales the constraint's information
    # Odometry constraints between consecutive submaps (Voxgraph: information x, y 1; yaw 2500)
    odometry_sigma_xy: float = 1.0
    odometry_sigma_yaw: float = 0.02
    # Robust kernel on registration and loop-closure constraints
    robust_kernel: str = "cauchy"
    robust_k: float = 2.0
    # Loop closure from visual place recognition (off, as in the paper's main runs)
    loop_closure: bool = False
    loop_keyframe_interval: float = 2.0  # seconds between keyframes kept for place recognition
    loop_max_features: int = 500
    loop_min_score: float = 0.15
    loop_min_inliers: int = 20
    loop_min_age: float = 30.0  # seconds: candidates must be at least this much older
    loop_sigma_xy: float = 0.5  # a closure fixes two frames, but a submap built on drifting odometry is not rigid
    loop_sigma_yaw: float = 0.05
    loop_max_error: float = 3.0  # reject a closure whose error after optimisation exceeds this (sigmas)
    # The 2D map sliced from the fused TSDF
    grid_min_height: float = 0.2
    grid_max_height: float = 1.5
    grid_resolution: float = 0.1
    write_mesh: bool = True  # map.ply mesh (marching cubes) in the run folder, if there is one

    def __post_init__(self) -> None:
        positive = [
            "voxel_size", "truncation", "max_ray_length", "integration_stride", "submap_interval",
            "registration_sampling_ratio", "registration_min_points", "registration_max_points",
            "registration_max_rms", "registration_max_correction", "registration_effective_points",
            "odometry_sigma_xy", "odometry_sigma_yaw", "robust_k", "loop_keyframe_interval", "loop_max_features",
            "loop_min_inliers", "loop_sigma_xy", "loop_sigma_yaw", "loop_max_error", "grid_resolution",
        ]
        for name in positive:
            value = getattr(self, name)
            if not math.isfinite(value) or value <= 0:
                raise InputError(f"submap parameter {name} must be positive, got {value!r}")
        for name in ("camera_height", "registration_min_overlap_area", "loop_min_score", "loop_min_age"):
            value = getattr(self, name)
            if not math.isfinite(value) or value < 0:
                raise InputError(f"submap parameter {name} must be >= 0, got {value!r}")
        if self.truncation <= self.voxel_size:
            raise InputError(f"truncation ({self.truncation}) must exceed voxel_size ({self.voxel_size})")
        if self.registration_sampling_ratio > 1:
            raise InputError(f"registration_sampling_ratio must be in (0, 1], got {self.registration_sampling_ratio}")
        if self.robust_kernel not in ("cauchy", "huber", "none"):
            raise InputError(f"robust_kernel must be cauchy, huber or none, got {self.robust_kernel!r}")
        if self.grid_max_height <= self.grid_min_height:
            raise InputError("grid_max_height must exceed grid_min_height")

    @classmethod
    def from_params(cls, params: dict[str, Any]) -> "SubmapConfig":
        """Build from `--param` values (JSON-decoded or strings), checking names and types."""
        types = {f.name: f.type for f in fields(cls)}
        unknown = sorted(set(params) - set(types))
        if unknown:
            raise InputError(
                f"method 'submap': unknown parameter(s) {', '.join(unknown)}; valid: {', '.join(sorted(types))}"
            )
        values = {}
        for key, raw in params.items():
            values[key] = _coerce(key, raw, types[key])
        return cls(**values)

    def to_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


def _coerce(key: str, raw: Any, kind: Any) -> Any:
    kind = kind if isinstance(kind, str) else kind.__name__
    if kind == "bool":
        if isinstance(raw, bool):
            return raw
        if isinstance(raw, str) and raw.lower() in ("true", "false", "1", "0", "yes", "no", "on", "off"):
            return raw.lower() in ("true", "1", "yes", "on")
        if isinstance(raw, int) and raw in (0, 1):
            return bool(raw)
        raise InputError(f"submap parameter {key} must be true or false, got {raw!r}")
    if kind == "int":
        if isinstance(raw, bool):
            raise InputError(f"submap parameter {key} must be an integer, got {raw!r}")
        try:
            value = float(raw)
        except (TypeError, ValueError):
            raise InputError(f"submap parameter {key} must be an integer, got {raw!r}") from None
        if not value.is_integer():
            raise InputError(f"submap parameter {key} must be an integer, got {raw!r}")
        return int(value)
    if kind == "float":
        if isinstance(raw, bool):
            raise InputError(f"submap parameter {key} must be a number, got {raw!r}")
        try:
            value = float(raw)
        except (TypeError, ValueError):
            raise InputError(f"submap parameter {key} must be a number, got {raw!r}") from None
        if not math.isfinite(value):
            raise InputError(f"submap parameter {key} must be a finite number, got {raw!r}")
        return value
    return str(raw)
