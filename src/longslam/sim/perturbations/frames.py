"""Frames that never arrive: a share dropped at random, and bursts of seconds with none.

A dropped frame is absent, as a real camera's is: the sequence has no colour or depth image for
it, so a method sees a gap in time between the frames around it; the ground truth and the
odometry keep their poses (the wheels and the motion capture do not stop when a camera drops a
frame). The first frame is never dropped (`stream.perturbed_frames`), so every run starts where
its ground truth does.
"""

from __future__ import annotations

import numpy as np

from longslam.sim.perturbations.base import FrameContext, Perturbation
from longslam.sim.perturbations.stretches import PERIOD_S, in_stretch


class Drop(Perturbation):
    """Each frame dropped with probability `level`, drawn per frame: a higher share drops the
    frames a lower one does, and more."""

    name = "drop"
    default_level = 0.1
    high = 0.95
    meaning = "a share of frames dropped, > 0 and <= 0.95"

    def drops(self, frame: FrameContext, rng: np.random.Generator) -> bool:
        return bool(rng.random() < self.level)


class DropBurst(Perturbation):
    """Every frame of a burst of `level` seconds dropped, one burst in each minute of the route."""

    name = "drop-burst"
    default_level = 1.0
    high = PERIOD_S / 2
    meaning = f"seconds without frames, one burst a minute, > 0 and <= {PERIOD_S / 2:g}"

    def drops(self, frame: FrameContext, rng: np.random.Generator) -> bool:
        return in_stretch(self.name, frame.seed, frame.timestamp, frame.start, frame.end, self.level)
