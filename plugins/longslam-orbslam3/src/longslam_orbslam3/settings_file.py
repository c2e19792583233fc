"""ORB-SLAM3's settings file (OpenCV YAML, `File.version: "1.0"`) for a longslam camera."""

from __future__ import annotations

import numpy as np

from longslam.core.frame import Intrinsics
from longslam_orbslam3.config import OrbSlam3Config, close_depth_factor

DEPTH_MAP_FACTOR = 5000.0  # depth goes in as TUM's 16-bit PNG values: metres x 5000


def fps_from_stamps(stamps: np.ndarray, default: float = 10.0) -> float:
    """The frame rate the stamps show (median step), for ORB-SLAM3's Camera.fps."""
    steps = np.diff(np.asarray(stamps, dtype=np.float64))
    steps = steps[steps > 0]
    if not len(steps):
        return default
    return float(1.0 / np.median(steps))


def settings_yaml(intrinsics: Intrinsics, config: OrbSlam3Config, fps: float, max_depth: float | None = None) -> str:
    """The settings text. Images are undistorted (longslam renders a pinhole camera), RGB order."""
    values = [
        ("File.version", '"1.0"'),
        ("Camera.type", '"PinHole"'),
        ("Camera1.fx", intrinsics.fx), ("Camera1.fy", intrinsics.fy),
        ("Camera1.cx", intrinsics.cx), ("Camera1.cy", intrinsics.cy),
        ("Camera1.k1", 0.0), ("Camera1.k2", 0.0), ("Camera1.p1", 0.0), ("Camera1.p2", 0.0),
        ("Camera.width", int(intrinsics.width)), ("Camera.height", int(intrinsics.height)),
        # ORB-SLAM3 keeps only whole frames per second (its Settings reads an int).
        ("Camera.fps", max(1, int(round(fps)))),
        ("Camera.RGB", 1),
        ("Stereo.ThDepth", close_depth_factor(config, max_depth)),
        ("Stereo.b", config.baseline),
        ("RGBD.DepthMapFactor", DEPTH_MAP_FACTOR),
        ("ORBextractor.nFeatures", int(config.features)),
        ("ORBextractor.scaleFactor", config.scale_factor),
        ("ORBextractor.nLevels", int(config.levels)),
        ("ORBextractor.iniThFAST", int(config.ini_th_fast)),
        ("ORBextractor.minThFAST", int(config.min_th_fast)),
        # The viewer's settings are read even when the viewer is off.
        ("Viewer.KeyFrameSize", 0.05), ("Viewer.KeyFrameLineWidth", 1.0), ("Viewer.GraphLineWidth", 0.9),
        ("Viewer.PointSize", 2.0), ("Viewer.CameraSize", 0.08), ("Viewer.CameraLineWidth", 3.0),
        ("Viewer.ViewpointX", 0.0), ("Viewer.ViewpointY", -0.7), ("Viewer.ViewpointZ", -1.8),
        ("Viewer.ViewpointF", 500.0),
    ]

    def text(value: object) -> str:
        if isinstance(value, float):
            return repr(float(value)) if np.isfinite(value) else "0.0"
        return str(value)

    lines = ["%YAML:1.0", "# written by longslam-orbslam3 from the sequence's camera and the method's parameters"]
    lines += [f"{key}: {text(value)}" for key, value in values]
    return "\n".join(lines) + "\n"
