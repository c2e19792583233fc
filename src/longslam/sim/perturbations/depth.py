"""The depth image perturbed: out of step with the colour, lost in bursts, cut short in range."""

from __future__ import annotations

import numpy as np

from longslam.core.depth_cut import depth_within
from longslam.core.depth_warp import move_at_velocity, reproject_depth
from longslam.sim.perturbations.base import FrameContext, Perturbation
from longslam.sim.perturbations.stretches import PERIOD_S, in_stretch


class DepthOffset(Perturbation):
    """Colour and depth out of step: the depth delivered with a colour image stamped t is the
    scene as seen from where the camera was at t - level (a positive level: depth lags colour; a
    negative one: it leads), both still stamped t, as with a camera whose two streams are not
    synchronised. The depth is the frame's own, reprojected into that pose: the camera's true
    velocity over the step on the offset's side of the stamp (the step from the previous frame for
    a lag, the step to the next for a lead), held constant over the offset, so any offset works,
    not only whole frames of the render; pixels the move uncovers have no return (0)."""

    name = "depth-offset"
    default_level = 0.05
    low = -0.5
    high = 0.5
    meaning = "seconds the depth lags the colour (negative: leads), not 0, between -0.5 and 0.5"

    @classmethod
    def level_problem(cls, level: float) -> str | None:
        if level == 0:
            return f"level 0 changes nothing; expected {cls.meaning}"
        return super().level_problem(level)

    def perturb(self, rgb, depth, frame: FrameContext, rng: np.random.Generator):
        before = frame.motion_before if frame.motion_before is not None else frame.motion
        motion = before if self.level > 0 else frame.motion
        # -level: the depth's moment, relative to the colour's
        rotation, moved = move_at_velocity(motion.angular_velocity, motion.linear_velocity, -self.level)
        return rgb, reproject_depth(depth, frame.intrinsics, rotation, moved)


class DepthDropout(Perturbation):
    """Depth lost in bursts: every pixel without a return for `level` seconds, once in each minute
    of the route (a USB stream stalling, another camera's projector, sunlight), colour unaffected."""

    name = "depth-dropout"
    default_level = 1.0
    high = PERIOD_S / 2
    meaning = f"seconds without depth, one burst a minute, > 0 and <= {PERIOD_S / 2:g}"

    def perturb(self, rgb, depth, frame: FrameContext, rng: np.random.Generator):
        if in_stretch(self.name, frame.seed, frame.timestamp, frame.start, frame.end, self.level):
            return rgb, np.zeros_like(depth)
        return rgb, depth


class DepthRange(Perturbation):
    """Depth cut short: no return beyond `level` metres, colour unaffected and the rest of the
    depth exact. It separates what a sensor's range costs from what its noise costs: a Kinect v1
    returns nothing beyond 4.5 m, so the ideal sensor at `depth-range=4.5` has the Kinect's reach
    without its noise, holes or quantisation (docs/sensors.md)."""

    name = "depth-range"
    default_level = 4.5
    meaning = "metres beyond which depth has no return, > 0"

    def perturb(self, rgb, depth, frame: FrameContext, rng: np.random.Generator):
        return rgb, depth_within(depth, self.level)
