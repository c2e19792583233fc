"""The Intel RealSense D435 (active IR stereo), after Intel's datasheet and its depth-quality
whitepaper.

Sources of the constants:

- RMS depth error growing as z^2, about 2 % at 2 m: Intel RealSense D400 Series Product Family
  Datasheet (rev. 005 onward), "Depth accuracy: < 2 % at 2 m" for the D435; z^2 from the
  whitepaper "Best-Known-Methods for Tuning Intel RealSense D400 Depth Cameras for Best
  Performance" (Grunnet-Jepsen et al.), sec. "Depth RMS error" = z^2 * subpixel / (f * b). So
  sigma(z) = 0.02 * 2 m * (z / 2 m)^2 = 0.01 z^2 m: 1 cm at 1 m, 4 cm at 2 m, 16 cm at 4 m.
  The whitepaper's formula with its typical 0.08 px subpixel at 848 x 480 gives a third of
  that for a well-textured target; the datasheet's bound is the choice here. The noise is drawn
  independently per pixel (a choice: real stereo noise is correlated over the matching window).
- Range 0.3-10 m: the datasheet's ideal range for the D435 (the render's own max_depth, 8 m by
  default, still applies).
- The invalid band on the left edge: the left imager is the reference and the right one, b =
  50 mm away (datasheet), does not see the image's left strip. Whitepaper, sec. "Invalid depth
  band": its width in pixels is b * f / Z for a scene at Z, here per pixel with its own depth.
- Speckle holes on low-texture surfaces: stereo matching fails where the image has no texture.
  Where the grey image's local std over 7 x 7 px is below `texture_threshold` (4 DN), seeds of
  holes are drawn with probability `speckle_seed` (4 %) and grown to 3 x 3 px, so about 30 % of
  such a surface is lost in small speckles. All three numbers are choices; the emitter's
  pattern, which textures a blank wall at short range in the real device, is not modelled.
- Colour: `ColourNoise`'s defaults, a choice (see there).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from longslam.core.frame import Intrinsics
from longslam.sim.sensors.base import FrameMotion, SensorModel
from longslam.sim.sensors.colour import ColourNoise

TEXTURE_WINDOW = 7  # pixels


@dataclass(frozen=True)
class RealSenseD435(SensorModel):
    name: str = "realsense-d435"
    relative_rms_at_2m: float = 0.02
    baseline: float = 0.050  # m, between the two IR imagers
    min_range: float = 0.3  # m
    max_range: float = 10.0  # m
    texture_threshold: float = 4.0  # DN of local std
    speckle_seed: float = 0.04  # probability a low-texture pixel seeds a 3 x 3 hole
    colour: ColourNoise = field(default_factory=ColourNoise)

    def sigma(self, z: np.ndarray | float) -> np.ndarray:
        """RMS depth error (m) at depth z (m)."""
        return self.relative_rms_at_2m * 2.0 * (np.asarray(z) / 2.0) ** 2

    def band(self, depth: np.ndarray, intrinsics: Intrinsics) -> np.ndarray:
        """The left-edge pixels the right imager does not see: column < b * fx / z."""
        with np.errstate(divide="ignore"):
            width = np.where(depth > 0, self.baseline * intrinsics.fx / depth, 0.0)
        return np.arange(depth.shape[1])[None, :] < width

    def low_texture(self, rgb: np.ndarray) -> np.ndarray:
        grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY).astype(np.float32)
        size = (TEXTURE_WINDOW, TEXTURE_WINDOW)
        mean = cv2.blur(grey, size)
        var = cv2.blur(grey * grey, size) - mean * mean
        return np.sqrt(np.maximum(var, 0.0)) < self.texture_threshold

    def expected_speckle_share(self) -> float:
        """The share of a large low-texture surface lost to speckles: 1 - (1 - p)^9."""
        return 1.0 - (1.0 - self.speckle_seed) ** 9

    def sense(self, rgb, depth, intrinsics, motion: FrameMotion, rng: np.random.Generator):
        # Matching works on the clean scene's texture (the IR images are not the colour camera's).
        low = self.low_texture(rgb)
        rgb = self.colour.apply(rgb, intrinsics, motion, rng, self.name)
        z = depth.astype(np.float32)
        seeds = (low & (rng.random(z.shape, dtype=np.float32) < self.speckle_seed)).astype(np.uint8)
        speckles = cv2.dilate(seeds, np.ones((3, 3), np.uint8)).astype(bool)
        noisy = z + self.sigma(z).astype(np.float32) * rng.standard_normal(z.shape, dtype=np.float32)
        keep = (z > 0) & ~speckles & ~self.band(z, intrinsics) & (noisy >= self.min_range) & (noisy <= self.max_range)
        return rgb, np.where(keep, noisy, np.float32(0)).astype(np.float32)
