"""The Kinect v1 (structured light), after Khoshelham & Elberink 2012 and Nguyen, Izadi &
Lovell 2012.

Sources of the constants:

- Axial noise sigma_z(z) = 0.0012 + 0.0019 (z - 0.4)^2 m (z in m): Nguyen, Izadi & Lovell,
  "Modeling Kinect Sensor Noise for Improved 3D Reconstruction and Tracking", 3DIMPVT 2012,
  eq. 5, fitted for incidence angles up to about 60 deg. Their measurements are of the device's
  output, quantisation included, so the Gaussian drawn here is that sigma less the
  quantisation's own share (a uniform step q adds q^2 / 12 of variance): the output's std is
  the formula's.
- Lateral noise about 0.8 px (of the device's 640 x 480 IR image): Nguyen et al. 2012, sec. 4,
  sigma_L ~ 0.8 px over 10-60 deg. Drawn here as each depth pixel read from a neighbour offset
  by N(0, sigma) in u and v (scaled to the render's pixels), which moves every edge.
- Disparity quantised in 1/8 px steps, baseline b = 7.5 cm, IR focal length f = 580 px:
  Khoshelham & Elberink, "Accuracy and Resolution of Kinect Depth Data for Indoor Mapping
  Applications", Sensors 12 (2012), sec. 2.1 and 3.3 (depth = b f / d, d in 1/8 px, so the step
  grows as z^2 / (8 b f): 1.1 cm at 2 m, 4.6 cm at 4 m).
- Range 0.5-4.5 m: Khoshelham & Elberink 2012 recommend 1-3 m for mapping and report data to
  about 5 m; the device returns nothing below about 0.5 m. 4.5 m is the issue's choice.
- Holes in the projector's shadow: the projector sits b to the IR camera's right (seen from
  the camera; Khoshelham & Elberink 2012, fig. 1), so every near edge has a band of no return
  on its left as wide as the disparity step across it (`geometry.projector_shadow`).
- Holes at grazing angles: beyond 75 deg of incidence (a choice; Nguyen et al. 2012 fig. 5
  show the noise growing quickly past about 70 deg and returns failing toward 90 deg).
- Colour: `ColourNoise`'s defaults, a choice (see there).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import cv2
import numpy as np

from longslam.core.frame import Intrinsics
from longslam.sim.sensors.base import FrameMotion, SensorModel
from longslam.sim.sensors.colour import ColourNoise
from longslam.sim.sensors.geometry import incidence_cos, projector_shadow


@dataclass(frozen=True)
class KinectV1(SensorModel):
    name: str = "kinect-v1"
    axial_a: float = 0.0012  # m
    axial_b: float = 0.0019  # m per m^2
    axial_z0: float = 0.4  # m
    lateral_px: float = 0.8  # device pixels
    baseline: float = 0.075  # m, IR projector to IR camera
    focal_px: float = 580.0  # device pixels, the IR camera at 640 x 480
    disparity_step: float = 1.0 / 8.0  # device pixels
    min_range: float = 0.5  # m
    max_range: float = 4.5  # m
    max_incidence_deg: float = 75.0
    colour: ColourNoise = field(default_factory=ColourNoise)

    def axial_sigma(self, z: np.ndarray | float) -> np.ndarray | float:
        """The output's axial std (m) at depth z (m), quantisation included."""
        offset = np.asarray(z) - self.axial_z0
        return self.axial_a + self.axial_b * offset * offset

    def depth_step(self, z: np.ndarray | float) -> np.ndarray | float:
        """The quantisation step (m) at depth z: one disparity step."""
        z = np.asarray(z)
        return z * z * (self.disparity_step / (self.baseline * self.focal_px))

    def shadow(self, depth: np.ndarray, intrinsics: Intrinsics) -> np.ndarray:
        return projector_shadow(depth, intrinsics, self.baseline)

    def sense(self, rgb, depth, intrinsics, motion: FrameMotion, rng: np.random.Generator):
        rgb = self.colour.apply(rgb, intrinsics, motion, rng, self.name)
        z = depth.astype(np.float32)
        holes = self.shadow(z, intrinsics)
        holes |= incidence_cos(z, intrinsics) < math.cos(math.radians(self.max_incidence_deg))
        z = np.where(holes, np.float32(0), z)
        z = _lateral_jitter(z, self.lateral_px * intrinsics.fx / self.focal_px, rng)
        valid = z > 0
        sigma = self.axial_sigma(z)
        step = self.depth_step(z)
        drawn = np.sqrt(np.maximum(sigma * sigma - step * step / np.float32(12.0), 0.0))
        drawn *= rng.standard_normal(z.shape, dtype=np.float32)
        drawn += z
        # Disparity in units of one step, rounded, and back to depth.
        bf_steps = np.float32(self.baseline * self.focal_px / self.disparity_step)
        with np.errstate(divide="ignore", invalid="ignore"):
            steps = np.rint(bf_steps / drawn)
            quantised = bf_steps / steps
        in_range = valid & (steps > 0) & (quantised >= self.min_range) & (quantised <= self.max_range)
        return rgb, np.where(in_range, quantised, np.float32(0)).astype(np.float32, copy=False)


def _lateral_jitter(z: np.ndarray, sigma_px: float, rng: np.random.Generator) -> np.ndarray:
    """Each pixel read from the nearest pixel to (u, v) + N(0, sigma_px) in each axis."""
    h, w = z.shape
    u, v = _pixel_grid(h, w)
    offsets = rng.standard_normal((2, h, w), dtype=np.float32)
    offsets *= np.float32(sigma_px)
    offsets[0] += u
    offsets[1] += v
    return cv2.remap(z, offsets[0], offsets[1], cv2.INTER_NEAREST, borderMode=cv2.BORDER_REPLICATE)


@lru_cache(maxsize=4)
def _pixel_grid(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    u, v = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    u.flags.writeable = v.flags.writeable = False
    return u, v
