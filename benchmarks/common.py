"""What the benchmarks share: sequences made once in a work folder, runs scored the one way."""

from __future__ import annotations

from pathlib import Path

from longslam.simulate import simulate
from longslam.run.isolate import run_and_score  # noqa: F401 (the benchmarks import it from here)
from longslam.sim.noise import get_noise
from longslam.sim.routes import get_route


def sequence(work: Path, route: str, noise: str, seed: int) -> Path:
    """The sequence (route, noise, seed) under `work`, simulated the first time it is asked for
    (rendering is cached under LONGSLAM_CACHE, so another noise level or seed is cheap)."""
    path = work / f"{route}-{noise}-{seed}"
    if not path.exists():
        simulate(get_route(route), get_noise(noise), seed, path, progress=False)
    return path
