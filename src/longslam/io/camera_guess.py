"""Intrinsics of a sequence folder without camera.json: never guessed silently.

A real TUM RGB-D sequence keeps its camera in its folder name (`rgbd_dataset_freiburg1_xyz`):
the three Freiburg Kinects have published calibrations, for their 640 x 480 images. Any other
folder without camera.json needs the intrinsics from the user.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from pathlib import Path

from longslam.core.errors import InputError
from longslam.core.frame import Intrinsics

# TUM RGB-D's calibrated colour intrinsics (fx, fy, cx, cy) of each Freiburg camera, 640 x 480.
# https://cvg.cit.tum.de/data/datasets/rgbd-dataset/file_formats#intrinsic_camera_calibration_of_the_kinect
FREIBURG = {
    1: (517.3, 516.5, 318.6, 255.3),
    2: (520.9, 521.0, 325.1, 249.7),
    3: (535.4, 539.2, 320.1, 247.6),
}
FREIBURG_SIZE = (640, 480)
_FREIBURG_NAME = re.compile(r"^rgbd_dataset_freiburg([123])_")


def parse_intrinsics(text: str, what: str = "--intrinsics") -> tuple[float, float, float, float]:
    """'fx,fy,cx,cy' in pixels -> four finite numbers, fx and fy positive."""
    parts = [p.strip() for p in str(text).split(",")]
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 4 or not all(math.isfinite(v) for v in values) or values[0] <= 0 or values[1] <= 0:
        raise InputError(f"{what} {text!r}: expected fx,fy,cx,cy in pixels (four numbers, fx and fy positive)")
    return values  # type: ignore[return-value]


def intrinsics_without_camera_json(
    folder: Path, width: int, height: int, given: Sequence[float] | str | None = None
) -> tuple[Intrinsics, str]:
    """The intrinsics of a folder whose camera.json is missing, and where they came from."""
    if given is not None:
        fx, fy, cx, cy = parse_intrinsics(given if isinstance(given, str) else ",".join(map(str, given)))
        return Intrinsics(width, height, fx, fy, cx, cy), "given (--intrinsics)"
    match = _FREIBURG_NAME.match(Path(folder).resolve().name)
    if match is not None:
        camera = int(match[1])
        if (width, height) != FREIBURG_SIZE:
            raise InputError(
                f"{folder}: the name says TUM freiburg{camera}, whose calibration is for 640 x 480 images, "
                f"but the images are {width} x {height}; give the intrinsics with --intrinsics fx,fy,cx,cy "
                "or a camera.json"
            )
        return Intrinsics(width, height, *FREIBURG[camera]), f"TUM freiburg{camera} calibration (from the folder name)"
    raise InputError(
        f"{folder} has no camera.json and its name does not say which camera took it "
        f"(rgbd_dataset_freiburg1/2/3_*); give the intrinsics with --intrinsics fx,fy,cx,cy, or write "
        f"{Path(folder) / 'camera.json'} with width, height, fx, fy, cx, cy"
    )
