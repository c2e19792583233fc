"""Colour noise of a real camera: motion blur over the exposure, shot and read noise, and
optionally the steps of an auto-exposure gain.

Every constant here is a choice, not a measurement of one device (neither the Kinect v1's nor
the D435's colour camera has published noise figures); they are chosen to be typical of an
8-bit consumer colour camera indoors:

- exposure 1/60 s: an auto-exposure indoors under office light; at the robot's 90 deg/s turn
  and 320 px across 90 deg (fx = 160 px) it smears a frame over about 4 px.
- shot noise: variance `shot_gain * I` (DN^2) for a pixel of value I, i.e. an 8-bit value is
  1/shot_gain collected electrons; shot_gain 0.1 gives 5 DN std at full scale.
- read noise: `read_noise` DN std on every pixel whatever its value (1.5 DN).
- gain steps (off unless `gain_period_s` > 0): every `gain_period_s` seconds the gain is redrawn
  uniformly from 1 +- `gain_step`, as an auto-exposure that hunts between steps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from longslam.core.frame import Intrinsics
from longslam.sim.sensors.base import FrameMotion, frame_rng

# Below this length (pixels) a blur is not drawn: it would change nothing at 8 bits.
MIN_BLUR_PX = 0.5


@dataclass(frozen=True)
class ColourNoise:
    exposure_s: float = 1.0 / 60.0
    shot_gain: float = 0.1  # DN^2 of variance per DN of signal
    read_noise: float = 1.5  # DN
    gain_period_s: float = 0.0  # 0: no auto-exposure steps
    gain_step: float = 0.15

    def blur_px(self, intrinsics: Intrinsics, motion: FrameMotion) -> tuple[float, float]:
        """The image-centre shift (du, dv) in pixels during the exposure: a turn about the camera's
        y axis moves the image sideways, one about x up or down. Translation is left out: at the
        robot's 1.5 m/s it moves a wall 1 m away by a pixel in 1/60 s, a turn by four."""
        wx, wy, _ = (float(v) for v in motion.angular_velocity)
        return -intrinsics.fx * wy * self.exposure_s, intrinsics.fy * wx * self.exposure_s

    def apply(
        self,
        rgb: np.ndarray,
        intrinsics: Intrinsics,
        motion: FrameMotion,
        rng: np.random.Generator,
        sensor: str = "",
        seed: int = 0,
    ) -> np.ndarray:
        image = rgb.astype(np.float32)
        du, dv = self.blur_px(intrinsics, motion)
        length = math.hypot(du, dv)
        if length >= MIN_BLUR_PX:
            image = cv2.filter2D(image, -1, _line_kernel(du, dv), borderType=cv2.BORDER_REFLECT)
        if self.gain_period_s > 0:
            # One draw per period, from a generator of its own: every frame of the period agrees.
            epoch = int(math.floor(motion.timestamp / self.gain_period_s))
            gain = 1.0 + self.gain_step * float(frame_rng(f"{sensor}/gain", seed, epoch).uniform(-1.0, 1.0))
            image *= np.float32(gain)
        # variance = shot_gain * I + read_noise^2, in place: a frame is 230k values, done at 10 Hz.
        std = np.maximum(image, 0.0)
        std *= np.float32(self.shot_gain)
        std += np.float32(self.read_noise**2)
        np.sqrt(std, out=std)
        std *= rng.standard_normal(image.shape, dtype=np.float32)
        image += std
        image += np.float32(0.5)
        np.clip(image, 0, 255, out=image)
        return image.astype(np.uint8)


def _line_kernel(du: float, dv: float) -> np.ndarray:
    """A normalised box along the segment from -(du, dv)/2 to (du, dv)/2, anti-aliased."""
    half = int(math.ceil(max(abs(du), abs(dv)) / 2)) + 1
    size = 2 * half + 1
    steps = max(2, int(math.ceil(4 * math.hypot(du, dv))))
    kernel = np.zeros((size, size), np.float32)
    for t in np.linspace(-0.5, 0.5, steps):
        x, y = half + t * du, half + t * dv
        x0, y0 = int(math.floor(x)), int(math.floor(y))
        fx, fy = x - x0, y - y0
        kernel[y0, x0] += (1 - fx) * (1 - fy)
        kernel[y0, x0 + 1] += fx * (1 - fy)
        kernel[y0 + 1, x0] += (1 - fx) * fy
        kernel[y0 + 1, x0 + 1] += fx * fy
    return kernel / kernel.sum()
