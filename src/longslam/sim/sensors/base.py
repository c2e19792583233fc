"""What a sensor model is: the clean render of one frame in, what a real camera delivers out.

A model is a small object with a `name` and one method, `sense`, that turns the cached clean
colour and depth of a frame into the noisy ones. It gets the true motion of the camera during
the frame (for motion blur) and a random generator made for that frame alone, so a frame is the
same whether a run starts at the beginning or not, and the same in `simulate` and in a study.

One's own model is a subclass registered through the `longslam.sensors` entry point (see
`longslam.sim.sensors.catalog`)::

    class Dusty(SensorModel):
        name = "dusty"
        def sense(self, rgb, depth, intrinsics, motion, rng):
            depth = depth.copy()
            depth[rng.random(depth.shape) < 0.05] = 0.0   # 5 % of the returns lost
            return rgb, depth
"""

from __future__ import annotations

import dataclasses
import zlib
from dataclasses import dataclass

import numpy as np

from longslam.core.frame import Intrinsics


@dataclass(frozen=True)
class FrameMotion:
    """The camera's true motion while a frame is exposed, in the camera frame (OpenCV axes)."""

    timestamp: float  # seconds
    angular_velocity: np.ndarray  # (3,) rad/s about the camera's x, y, z axes
    linear_velocity: np.ndarray  # (3,) m/s along the camera's x, y, z axes

    @classmethod
    def still(cls, timestamp: float = 0.0) -> "FrameMotion":
        return cls(float(timestamp), np.zeros(3), np.zeros(3))


class SensorModel:
    """The ideal sensor, and the base of every other: colour and depth as rendered."""

    name: str = "ideal"

    @property
    def is_ideal(self) -> bool:
        """Whether the model leaves every frame as rendered (then a sequence links the cached frames)."""
        return type(self).sense is SensorModel.sense

    def sense(
        self, rgb: np.ndarray, depth: np.ndarray, intrinsics: Intrinsics, motion: FrameMotion, rng: np.random.Generator
    ) -> tuple[np.ndarray, np.ndarray]:
        """rgb (H, W, 3) uint8 and depth (H, W) float32 metres (0 = no return) as the camera
        would deliver them; the inputs are not modified."""
        return rgb, depth

    def describe(self) -> dict:
        """The model's name and constants, for meta.json and a run's record."""
        # Subclasses are dataclasses; mypy does not narrow a plain class to the dataclass protocol.
        fields: dict[str, object] = dataclasses.asdict(self) if dataclasses.is_dataclass(self) else {}  # type: ignore[call-overload]
        return {"name": self.name, **fields}


def frame_rng(sensor: str, seed: int, index: int) -> np.random.Generator:
    """The generator of one frame's draws, keyed by (sensor, seed, frame index) alone."""
    # crc32 rather than hash(): Python salts str hashes per process.
    return np.random.default_rng([zlib.crc32(sensor.encode("utf-8")), int(seed), int(index)])
