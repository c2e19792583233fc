"""Perturbations: the ways a real camera fails beyond its noise (frames dropped, colour and depth
out of step, the lights dimmed, motion blur, depth lost in bursts, depth cut short in range),
applied after the sensor model to frames rendered once."""

from longslam.sim.perturbations.base import FrameContext, Perturbation, perturbation_rng
from longslam.sim.perturbations.catalog import get_perturbation, perturbation_names
from longslam.sim.perturbations.parse import NONE, canonical, parse_entry, parse_perturbations

__all__ = [
    "FrameContext",
    "NONE",
    "Perturbation",
    "canonical",
    "get_perturbation",
    "parse_entry",
    "parse_perturbations",
    "perturbation_names",
    "perturbation_rng",
]
