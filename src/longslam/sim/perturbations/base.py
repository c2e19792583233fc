"""What a perturbation is: one way a real camera fails, at a level, applied to the frames a
sensor model delivers.

A perturbation is a small object with a `name`, a `level` and two methods, both optional:
`drops` (whether a frame never reaches the method) and `perturb` (what becomes of a delivered
frame's images). Each gets the frame's own random generator, keyed by (perturbation name, seed,
frame index) alone, so a frame is perturbed the same whether a run starts at the beginning or
not, the same in `simulate` and in a study, and the same at every level: a higher level of
`drop` drops the frames of a lower one and more.

One's own perturbation is a subclass registered through the `longslam.perturbations` entry point
(see `longslam.sim.perturbations.catalog`)::

    class Snow(Perturbation):
        name = "snow"
        default_level = 0.01
        high = 1.0
        meaning = "a share of colour pixels turned white, > 0 and <= 1"
        def perturb(self, rgb, depth, frame, rng):
            rgb = rgb.copy()
            rgb[rng.random(depth.shape) < self.level] = 255
            return rgb, depth
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass

import numpy as np

from longslam.core.frame import Intrinsics
from longslam.sim.sensors.base import FrameMotion


@dataclass(frozen=True)
class FrameContext:
    """What a perturbation may know of one frame beside its images."""

    index: int  # the frame's index in the rendered sequence (before any frame is dropped)
    timestamp: float  # seconds
    start: float  # the sequence's first and last timestamps: stretches of the route lie between them
    end: float
    intrinsics: Intrinsics
    motion: FrameMotion  # the camera's true motion during the frame (the step to the next frame)
    seed: int
    # The step from the previous frame, which the camera made before this frame's stamp; None: the
    # same as `motion` (the first frame).
    motion_before: FrameMotion | None = None


class Perturbation:
    """The base of every perturbation; on its own it changes nothing.

    A subclass sets `name`, `default_level`, the open-closed range (`low`, `high`] of its level and
    `meaning` (what the level is, for errors and `longslam list`), and overrides `drops`,
    `perturb` or both. The level is checked before the class is made (`level_problem`)."""

    name: str = ""
    default_level: float = 1.0
    low: float = 0.0  # a level must be > low ...
    high: float = math.inf  # ... and <= high
    meaning: str = "a number > 0"

    def __init__(self, level: float | None = None):
        self.level = float(self.default_level if level is None else level)

    @classmethod
    def level_problem(cls, level: float) -> str | None:
        """None for a level this perturbation takes; else what is wrong with it."""
        if not math.isfinite(level) or not cls.low < level <= cls.high:
            return f"level {level_text(level)} is out of range; expected {cls.meaning}"
        return None

    @property
    def text(self) -> str:
        """NAME=LEVEL, as given to `simulate --perturb` and named in a study's run keys."""
        return f"{self.name}={level_text(self.level)}"

    @property
    def changes_images(self) -> bool:
        return type(self).perturb is not Perturbation.perturb

    @property
    def drops_frames(self) -> bool:
        return type(self).drops is not Perturbation.drops

    def drops(self, frame: FrameContext, rng: np.random.Generator) -> bool:
        """Whether the frame never reaches the method (its colour and depth both lost)."""
        return False

    def perturb(
        self, rgb: np.ndarray, depth: np.ndarray, frame: FrameContext, rng: np.random.Generator
    ) -> tuple[np.ndarray, np.ndarray]:
        """rgb (H, W, 3) uint8 and depth (H, W) float32 metres as the perturbed camera delivers
        them; the inputs are not modified."""
        return rgb, depth

    def describe(self) -> dict:
        """The perturbation's name, level and its meaning, for meta.json and a run's record."""
        return {"name": self.name, "level": self.level, "meaning": self.meaning}

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.text})"


def level_text(level: float) -> str:
    """The shortest text of a level that reads back as the same number: 0.1, 2, 1e-05."""
    text = repr(float(level))
    return text[:-2] if text.endswith(".0") else text


def perturbation_rng(name: str, seed: int, index: int) -> np.random.Generator:
    """The generator of one frame's draws for one perturbation, keyed by (name, seed, index) alone."""
    # The prefix keeps these draws apart from a sensor model's of the same name; crc32 rather than
    # hash(), which Python salts per process.
    return np.random.default_rng([zlib.crc32(f"perturbation/{name}".encode("utf-8")), int(seed), int(index)])
