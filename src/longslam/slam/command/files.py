"""The files the `command` method writes for a program besides the TUM folder: an associations
file and an ORB-SLAM-style camera settings file."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from longslam.core.frame import Intrinsics
from longslam.io.atomic import write_text
from longslam.io.sequence.layout import DEPTH_DIR, DEPTH_SCALE, RGB_DIR

# ORB-SLAM3's Examples/RGB-D/TUM1.yaml values for what longslam's camera does not say.
TH_DEPTH = 40.0  # close points: within 40 baselines (3.1 m)
BASELINE = 0.07732  # m, the virtual stereo pair ORB-SLAM makes of a depth image (a Kinect's)
ORB_EXTRACTOR = (("nFeatures", 1000), ("scaleFactor", 1.2), ("nLevels", 8), ("iniThFAST", 20), ("minThFAST", 7))
VIEWER = (
    ("KeyFrameSize", 0.05),
    ("KeyFrameLineWidth", 1.0),
    ("GraphLineWidth", 0.9),
    ("PointSize", 2.0),
    ("CameraSize", 0.08),
    ("CameraLineWidth", 3.0),
    ("ViewpointX", 0.0),
    ("ViewpointY", -0.7),
    ("ViewpointZ", -1.8),
    ("ViewpointF", 500.0),
)


def associations_text(stamp_texts: list[str]) -> str:
    """TUM's associate.py output for a folder whose rgb and depth images share their stamps:
    `t rgb/t.png t depth/t.png` a line. No comment line: ORB-SLAM's `rgbd_tum` reads every line
    as a frame."""
    return "".join(f"{t} {RGB_DIR}/{t}.png {t} {DEPTH_DIR}/{t}.png\n" for t in stamp_texts)


def frame_rate(stamps: np.ndarray, default: float = 10.0) -> float:
    """Frames per second, from the median step between stamps."""
    steps = np.diff(np.asarray(stamps, dtype=np.float64))
    steps = steps[steps > 0]
    return float(1.0 / np.median(steps)) if len(steps) else default


def _number(value: float) -> str:
    return repr(float(value))


def settings_text(intrinsics: Intrinsics, fps: float) -> str:
    """An OpenCV YAML camera settings file as ORB-SLAM3 1.0 reads it (`File.version: "1.0"`,
    `Camera1.*`, TUM1.yaml's other values), with the keys ORB-SLAM2 and ORB-SLAM3's older parser
    read instead (`Camera.fx`..., `Camera.bf`, `ThDepth`, `DepthMapFactor`) beside them: each
    reads its own keys and ignores the others'. Images are undistorted, colour in RGB order."""
    k = intrinsics
    pinhole = (
        ("fx", k.fx),
        ("fy", k.fy),
        ("cx", k.cx),
        ("cy", k.cy),
        ("k1", 0.0),
        ("k2", 0.0),
        ("p1", 0.0),
        ("p2", 0.0),
    )
    lines = [
        "%YAML:1.0",
        "# written by longslam's `command` method from the sequence's camera; other values are ORB-SLAM3's TUM1.yaml",
        'File.version: "1.0"',
        'Camera.type: "PinHole"',
        *(f"Camera1.{key}: {_number(value)}" for key, value in pinhole),
        f"Camera.width: {int(k.width)}",
        f"Camera.height: {int(k.height)}",
        f"Camera.fps: {max(1, int(round(fps)))}",  # ORB-SLAM3 1.0 reads a whole number
        "Camera.RGB: 1",
        f"Stereo.ThDepth: {_number(TH_DEPTH)}",
        f"Stereo.b: {_number(BASELINE)}",
        f"RGBD.DepthMapFactor: {_number(DEPTH_SCALE)}",
        *(f"ORBextractor.{key}: {value}" for key, value in ORB_EXTRACTOR),
        *(f"Viewer.{key}: {_number(value)}" for key, value in VIEWER),
        "# the same camera for ORB-SLAM2 (and ORB-SLAM3 without File.version)",
        *(f"Camera.{key}: {_number(value)}" for key, value in pinhole),
        f"Camera.bf: {_number(k.fx * BASELINE)}",
        f"ThDepth: {_number(TH_DEPTH)}",
        f"DepthMapFactor: {_number(DEPTH_SCALE)}",
    ]
    return "\n".join(lines) + "\n"


def write_settings(path: Path, intrinsics: Intrinsics, stamps: np.ndarray) -> None:
    write_text(path, settings_text(intrinsics, frame_rate(stamps)))
