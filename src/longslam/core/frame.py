"""One RGB-D frame as a method sees it, and the pinhole intrinsics of its camera."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np

from longslam.core.errors import InputError


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
                int(data["width"]),
                int(data["height"]),
                float(data["fx"]),
                float(data["fy"]),
                float(data["cx"]),
                float(data["cy"]),
            )
        except KeyError as missing:
            raise InputError(f"{source}: missing field {missing} (expected width, height, fx, fy, cx, cy)") from None
        except (TypeError, ValueError) as err:
            raise InputError(f"{source}: intrinsics fields must be numbers ({err})") from None


class _LoadedOnUse:
    """A Frame attribute given as an array, or as a function that loads it when first read."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.slot = "_" + name

    def __get__(self, frame: "Frame | None", owner: type | None = None):
        if frame is None:
            return self
        value = getattr(frame, self.slot)
        if callable(value):
            value = value()
            setattr(frame, self.slot, value)
        return value

    def __set__(self, frame: "Frame", value) -> None:
        setattr(frame, self.slot, value)


class Frame:
    """One RGB-D frame: index, timestamp (s), rgb (H, W, 3) uint8, depth (H, W) float32 metres (0
    where there is no return), the odometry's (4, 4) camera-in-world pose (None for a recorded
    sequence without one: real TUM sequences carry no odometry) and the intrinsics.

    rgb and depth may be given as arrays or as functions that load them on first use, so that a
    method that looks at the images of one frame in ten (a keyframe graph on wheel odometry) makes
    the reader decode one in ten.
    """

    __slots__ = ("index", "timestamp", "odometry", "intrinsics", "_rgb", "_depth")
    rgb = _LoadedOnUse()
    depth = _LoadedOnUse()

    def __init__(
        self,
        index: int,
        timestamp: float,
        rgb: np.ndarray | Callable[[], np.ndarray],
        depth: np.ndarray | Callable[[], np.ndarray],
        odometry: np.ndarray | None,
        intrinsics: Intrinsics,
    ):
        self.index = index
        self.timestamp = timestamp
        self.rgb = rgb
        self.depth = depth
        self.odometry = odometry
        self.intrinsics = intrinsics

    def __repr__(self) -> str:
        return f"Frame(index={self.index}, timestamp={self.timestamp:.6f})"
