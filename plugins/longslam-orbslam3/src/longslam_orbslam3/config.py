"""The parameters of the `orbslam3` method: ORB-SLAM3's own settings, longslam's way.

Every field is set with `longslam run --method orbslam3 --param features=2000` or a study's
`[params.orbslam3]`; defaults are ORB-SLAM3's `Examples/RGB-D/TUM1.yaml` values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from longslam.core.errors import InputError


def _check(ok: bool, message: str) -> None:
    if not ok:
        raise InputError(f"method 'orbslam3': {message}")


@dataclass(frozen=True)
class OrbSlam3Config:
    # ORB extractor (ORBextractor.*): features per image, pyramid scale and levels, FAST thresholds
    features: int = 1000
    scale_factor: float = 1.2
    levels: int = 8
    ini_th_fast: int = 20
    min_th_fast: int = 7
    # RGB-D: points closer than th_depth x baseline are "close" (their depth trusted from one frame);
    # 0 puts that range at the camera's own max depth (8 m / 0.07732 m = 103.5 for longslam's
    # camera), since rendered depth is exact to its end. TUM1.yaml's 40 (3.1 m, a Kinect's
    # trustworthy range) leaves too few close points in a hall: measured on the demo route, large
    # noise, seed 0, 320 x 240, it lost tracking on 96 frames and made 4 maps (ATE 3.3 m), where
    # 100 tracked every frame (ATE 0.54 m).
    th_depth: float = 0.0
    # The baseline of the virtual stereo pair ORB-SLAM3 makes of a depth image (TUM1.yaml's Kinect)
    baseline: float = 0.07732
    # An ORB vocabulary in DBoW2's text format. Empty: $PYORBSLAM3_VOCAB if set, else longslam's
    # default vocabulary (trained on the `annex` building, not the evaluated one), built once.
    vocabulary: str = ""
    # Camera height above the floor where a sequence has no odometry to start from (the built-in
    # methods' default); with odometry the first frame starts at the first odometry pose.
    camera_height: float = 1.25
    # Frames go in no faster than `pace` x the sequence's own rate (its stamps), as ORB-SLAM3's
    # examples feed a dataset: its mapping and loop-closing threads run beside tracking, and fed
    # faster than a camera would, tracking outruns them (keyframes refused, tracking lost in turns).
    # 0: as fast as tracking goes.
    pace: float = 1.0
    # How long `finish` waits for a global bundle adjustment still running after the last frame
    # (ORB-SLAM3 1.0's Shutdown does not wait for it), seconds.
    gba_wait: float = 600.0

    def __post_init__(self) -> None:
        # Ranges keep a run within memory and within what ORB-SLAM3 accepts (it exits the process
        # on some bad settings rather than raising).
        _check(100 <= self.features <= 20000, f"features={self.features}: expected 100 to 20000 ORB features per image")
        _check(math.isfinite(self.scale_factor) and 1.0 < self.scale_factor <= 2.0,
               f"scale_factor={self.scale_factor}: expected more than 1 and at most 2")
        _check(1 <= self.levels <= 16, f"levels={self.levels}: expected 1 to 16 pyramid levels")
        _check(1 <= self.min_th_fast <= self.ini_th_fast <= 255,
               f"ini_th_fast={self.ini_th_fast}, min_th_fast={self.min_th_fast}: expected 1 <= min_th_fast <= ini_th_fast <= 255")
        _check(math.isfinite(self.th_depth) and 0.0 <= self.th_depth <= 1000.0,
               f"th_depth={self.th_depth}: expected 0 (the camera's max depth) to 1000 baselines")
        _check(math.isfinite(self.baseline) and 0.0 < self.baseline <= 1.0, f"baseline={self.baseline}: expected (0, 1] m")
        _check(math.isfinite(self.camera_height) and 0.0 < self.camera_height < 10.0,
               f"camera_height={self.camera_height}: expected (0, 10) m")
        _check(math.isfinite(self.pace) and 0.0 <= self.pace <= 1000.0, f"pace={self.pace}: expected 0 (no pacing) to 1000 x real time")
        _check(math.isfinite(self.gba_wait) and 0.0 <= self.gba_wait <= 86400.0, f"gba_wait={self.gba_wait}: expected 0 to 86400 s")


TUM_TH_DEPTH = 40.0  # ORB-SLAM3's TUM1.yaml, where the camera's range is not known


def close_depth_factor(config: OrbSlam3Config, max_depth: float | None) -> float:
    """Stereo.ThDepth as ORB-SLAM3 takes it: the parameter, or the camera's max depth in baselines."""
    if config.th_depth > 0.0:
        return config.th_depth
    if max_depth is None or not math.isfinite(max_depth) or max_depth <= 0.0:
        return TUM_TH_DEPTH
    return max_depth / config.baseline
