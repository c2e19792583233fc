"""The parameters of the `orbslam3` method: ORB-SLAM3's own settings, longslam's way.

Every field is set with `longslam run --method orbslam3 --param features=2000` or a study's
`[params.orbslam3]`; defaults are ORB-SLAM3's `Examples/RGB-D/TUM1.yaml` values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from longslam.core.errors import InputError
from longslam.core.parameter import check_declared, param


@dataclass(frozen=True)
class OrbSlam3Config:
    # Ranges keep a run within memory and within what ORB-SLAM3 accepts (it exits the process on
    # some bad settings rather than raising).
    features: int = param(1000, "ORB features per image (ORBextractor.nFeatures)", at_least=100, at_most=20000)
    scale_factor: float = param(
        1.2, "scale between the levels of the image pyramid (ORBextractor.scaleFactor)", above=1, at_most=2
    )
    levels: int = param(8, "levels of the image pyramid (ORBextractor.nLevels)", at_least=1, at_most=16)
    ini_th_fast: int = param(20, "FAST threshold tried first (ORBextractor.iniThFAST)", at_least=1, at_most=255)
    min_th_fast: int = param(
        7, "FAST threshold where the first finds too few corners (at most ini_th_fast)", at_least=1, at_most=255
    )
    # 0 puts that range at the camera's own max depth (8 m / 0.07732 m = 103.5 for longslam's
    # camera), since rendered depth is exact to its end; TUM1.yaml's 40 (3.1 m, a Kinect's
    # trustworthy range) leaves too few close points in a hall.
    th_depth: float = param(
        0.0,
        "points closer than th_depth x baseline are close, their depth trusted from one frame (0: the max depth)",
        at_least=0,
        at_most=1000,
        unit="baselines",
    )
    baseline: float = param(
        0.07732,
        "the baseline of the virtual stereo pair ORB-SLAM3 makes of a depth image (TUM1.yaml's Kinect)",
        above=0,
        at_most=1,
        unit="m",
    )
    vocabulary: str = param(
        "",
        "an ORB vocabulary in DBoW2's text format; empty: $PYORBSLAM3_VOCAB if set, else longslam's default one",
    )
    # With odometry the first frame starts at the first odometry pose.
    camera_height: float = param(
        1.25,
        "camera height above the floor where a sequence has no odometry to start from",
        above=0,
        below=10,
        unit="m",
    )
    # Its mapping and loop-closing threads run beside tracking; fed faster than a camera would,
    # tracking outruns them (keyframes refused, tracking lost in turns).
    pace: float = param(
        1.0,
        "frames go in no faster than pace x the sequence's rate, as ORB-SLAM3's examples feed one (0: no pacing)",
        at_least=0,
        at_most=1000,
    )
    gba_wait: float = param(
        600.0,
        "how long finish waits for a global bundle adjustment still running after the last frame",
        at_least=0,
        at_most=86400,
        unit="s",
    )

    def __post_init__(self) -> None:
        check_declared(self, "method 'orbslam3'")
        if self.min_th_fast > self.ini_th_fast:
            raise InputError(
                f"method 'orbslam3': min_th_fast ({self.min_th_fast}) must be at most ini_th_fast ({self.ini_th_fast})"
            )


TUM_TH_DEPTH = 40.0  # ORB-SLAM3's TUM1.yaml, where the camera's range is not known


def close_depth_factor(config: OrbSlam3Config, max_depth: float | None) -> float:
    """Stereo.ThDepth as ORB-SLAM3 takes it: the parameter, or the camera's max depth in baselines."""
    if config.th_depth > 0.0:
        return config.th_depth
    if max_depth is None or not math.isfinite(max_depth) or max_depth <= 0.0:
        return TUM_TH_DEPTH
    return max_depth / config.baseline
