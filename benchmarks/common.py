"""What the benchmarks share: sequences made once in a work folder, runs scored the one way."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

from longslam.sim.simulate import simulate
from longslam.run.scored_run import run_and_score  # noqa: F401 (the benchmarks import it from here)
from longslam.core.odometry_noise import get_noise
from longslam.sim.routes import get_route


def sequence(work: Path, route: str, noise: str, seed: int, sensor: str = "ideal") -> Path:
    """The sequence (route, noise, seed) under `work` through the sensor model `sensor`, simulated
    the first time it is asked for (rendering is cached under LONGSLAM_CACHE, so another noise
    level, seed or sensor is cheap)."""
    path = work / (f"{route}-{noise}-{seed}" if sensor == "ideal" else f"{route}-{sensor}-{noise}-{seed}")
    if not path.exists():
        simulate(get_route(route), get_noise(noise), seed, path, progress=False, sensor=sensor)
    return path


def run_process(command: list[str], log: Path, env: dict[str, str] | None = None) -> tuple[float, float, int]:
    """(wall seconds, peak RSS in MiB, exit status) of one child process (environment `env`, or
    this one's); its output goes to `log`."""
    wall, peak, _, code = run_process_usage(command, log, env)
    return wall, peak, code


def run_process_usage(command: list[str], log: Path,
                      env: dict[str, str] | None = None) -> tuple[float, float, float, int]:
    """`run_process`, with the child's CPU seconds (user + system) before the exit status: on a
    machine shared with other jobs the wall time grows with their load, its CPU time far less."""
    with open(log, "w") as out:
        start = time.perf_counter()
        child = subprocess.Popen(command, stdout=out, stderr=subprocess.STDOUT, env=env)
        # wait4 gives this child's own rusage (a fork of a large parent would inherit its peak).
        _, status, usage = os.wait4(child.pid, 0)
        wall = time.perf_counter() - start
    code = os.waitstatus_to_exitcode(status)
    if code:
        print(log.read_text()[-2000:], file=sys.stderr)
    return wall, usage.ru_maxrss / 1024.0, usage.ru_utime + usage.ru_stime, code
