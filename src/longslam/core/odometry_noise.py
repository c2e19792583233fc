"""The odometry noise model of the paper, with its units made explicit: the levels, and the
covariance a level implies. A sequence records its level in meta.json; the simulator draws the
noise (`longslam.sim.noise`), a bag export states its covariance.

Per frame, the odometry integrates the true motion plus two biases: a linear bias (metres per
frame) added to the forward step on frames where the robot translates, and an angular bias
(degrees per frame) added to the heading change on every frame. Both are drawn from zero-mean
Gaussians with the level's std and redrawn every `redraw_period` seconds of simulated time.
The odometry starts at the true first pose.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from longslam.core.errors import InputError
from longslam.core.registry import Registry


@dataclass(frozen=True)
class BiasNoise:
    name: str
    linear_std: float  # metres per frame
    angular_std_deg: float  # degrees per frame
    redraw_period: float = 10.0  # seconds

    def step_variances(self) -> tuple[float, float]:
        """Variances of one frame's odometry error that this model implies: (forward step in m^2,
        heading change in rad^2), in the robot's frame at the start of the step.

        The forward error of a step is the linear bias in force (zero-mean, std `linear_std`), the
        heading error the angular bias (std `angular_std_deg`, in radians here); the lateral step
        and the height carry no error. The biases are held for `redraw_period` seconds, so the
        errors of the steps inside one period are not independent: the error of n consecutive
        steps inside a period has n^2 times these variances (not n times), and steps in different
        periods are independent.
        """
        return self.linear_std**2, math.radians(self.angular_std_deg) ** 2


NOISE_LEVELS: Registry[BiasNoise] = Registry("noise level")
for _level in (
    BiasNoise("none", 0.0, 0.0),
    BiasNoise("small", 0.0015, 0.003),
    BiasNoise("medium", 0.003, 0.0075),
    BiasNoise("large", 0.0075, 0.015),
    BiasNoise("xlarge", 0.015, 0.025),
):
    NOISE_LEVELS.register(_level.name, _level)


def get_noise(name: str) -> BiasNoise:
    return NOISE_LEVELS.get(name)


def noise_of_meta(meta: dict, where: Path) -> BiasNoise:
    """The noise model the sequence's odometry was drawn with, from meta.json."""
    if "noise_linear_std" in meta and "noise_angular_std_deg" in meta:
        try:
            return BiasNoise(
                str(meta.get("noise", "sequence")),
                float(meta["noise_linear_std"]),
                float(meta["noise_angular_std_deg"]),
                float(meta.get("noise_redraw_period_s", 10.0)),
            )
        except (TypeError, ValueError):
            raise InputError(f"{where}/meta.json: noise_linear_std and noise_angular_std_deg must be numbers") from None
    if "noise" in meta:
        return get_noise(str(meta["noise"]))
    raise InputError(
        f"{where} has odometry.txt but its meta.json names no noise level (fields noise, or noise_linear_std "
        f"and noise_angular_std_deg), so the odometry's covariance is unknown; give it with "
        f"--odom-noise LEVEL (none, small, medium, large, xlarge)"
    )
