"""The colour image perturbed: the lights dimmed over a stretch of the route, and motion blur
beyond the sensor model's."""

from __future__ import annotations

import math

import cv2
import numpy as np

from longslam.sim.perturbations.base import FrameContext, Perturbation
from longslam.sim.perturbations.stretches import in_stretch
from longslam.sim.sensors.colour import MIN_BLUR_PX, ColourNoise, _line_kernel

EXPOSURE_STRETCH_S = 10.0  # how long the lights stay dimmed, once a minute


class Exposure(Perturbation):
    """A step in exposure: for `EXPOSURE_STRETCH_S` seconds in each minute of the route the colour
    image is `level` stops darker (times 2^-level), as when the lights of a corridor are off and
    the camera's exposure does not follow. Depth, from the camera's own infrared, is left as it is."""

    name = "exposure"
    default_level = 2.0
    high = 8.0
    meaning = f"stops darker for {EXPOSURE_STRETCH_S:g} s a minute, > 0 and <= 8"

    def perturb(self, rgb, depth, frame: FrameContext, rng: np.random.Generator):
        if not in_stretch(self.name, frame.seed, frame.timestamp, frame.start, frame.end, EXPOSURE_STRETCH_S):
            return rgb, depth
        dimmed = rgb.astype(np.float32) * np.float32(2.0**-self.level) + np.float32(0.5)
        return np.clip(dimmed, 0, 255).astype(np.uint8), depth


class Blur(Perturbation):
    """Motion blur over `level` seconds more of exposure, from the camera's true turn during the
    frame (as the sensor model's own blur; see `ColourNoise.blur_px`): a still or straight-driving
    camera is not blurred, a turning one is, in proportion."""

    name = "blur"
    default_level = 0.02
    high = 0.5
    meaning = "seconds of extra exposure, > 0 and <= 0.5"

    def blur_px(self, frame: FrameContext) -> tuple[float, float]:
        return ColourNoise(exposure_s=self.level).blur_px(frame.intrinsics, frame.motion)

    def perturb(self, rgb, depth, frame: FrameContext, rng: np.random.Generator):
        du, dv = self.blur_px(frame)
        if math.hypot(du, dv) < MIN_BLUR_PX:
            return rgb, depth
        blurred = cv2.filter2D(rgb.astype(np.float32), -1, _line_kernel(du, dv), borderType=cv2.BORDER_REFLECT)
        return np.clip(blurred + np.float32(0.5), 0, 255).astype(np.uint8), depth
