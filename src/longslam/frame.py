"""One RGB-D frame as a method sees it, and the pinhole intrinsics of its camera."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from longslam.errors import InputError


@dataclass(frozen=True)
class Intrinsics:
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @classmethod
    def from_fov(cls, width: int, height: int, hfov_deg: float) -> "Intrinsics":
        """Square pixels, principal point at the image centre, horizontal field of view."""
        if width <= 0 or height <= 0:
            raise InputError(f"image size must be positive, got width={width} height={height}")
        if not 0.0 < hfov_deg < 180.0:
            raise InputError(f"horizontal field of view must be in (0, 180) degrees, got {hfov_deg}")
        f = (width / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
        return cls(width, height, f, f, width / 2.0, height / 2.0)

    @property
    def matrix(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict, source: str = "intrinsics") -> "Intrinsics":
        try:
            return cls(
                int(data["width"]), int(data["height"]), float(data["fx"]), float(data["fy"]),
                float(data["cx"]), float(data["cy"]),
            )
        except KeyError as missing:
            raise InputError(f"{source}: missing field {missing} (expected width, height, fx, fy, cx, cy)") from None
        except (TypeError, ValueError) as err:
            raise InputError(f"{source}: intrinsics fields must be numbers ({err})") from None


@dataclass
class Frame:
    index: int
    timestamp: float  # seconds
    rgb: np.ndarray  # (H, W, 3) uint8
    depth: np.ndarray  # (H, W) float32 metres, 0 where there is no return
    # (4, 4) camera-in-world pose reported by the odometry; None for a recorded sequence that
    # has none (real TUM sequences carry no odometry).
    odometry: np.ndarray | None
    intrinsics: Intrinsics
