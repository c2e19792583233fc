"""What a sensor model costs: `longslam simulate` of a route with each sensor once the route is
rendered (wall time and peak memory from /usr/bin/time -v), and the model alone per frame.

    python benchmarks/sensors.py [--route paper-300m] [--noise large] [--seed 0] [--frames 200]
        [--sensors ideal kinect-v1 realsense-d435] [--work DIR]

The route must be rendered already (LONGSLAM_CACHE), as the issue's target is stated: the ideal
sensor's simulate hard-links the cached frames, any other decodes, senses and re-encodes them.
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def timed_simulate(route: str, noise: str, seed: int, sensor: str, out: Path) -> tuple[float, float]:
    """Wall seconds and peak resident MiB of `longslam simulate` as a user runs it."""
    installed = Path(sys.executable).with_name("longslam")  # the console script a user runs
    longslam = [str(installed)] if installed.is_file() else [sys.executable, "-m", "longslam"]
    command = ["/usr/bin/time", "-v", *longslam, "simulate", "--route", route,
               "--noise", noise, "--seed", str(seed), "--sensor", sensor, "--out", str(out), "--overwrite"]
    done = subprocess.run(command, capture_output=True, text=True, check=True)
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (?:(\d+):)?(\d+):([\d.]+)", done.stderr)
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", done.stderr)
    hours, minutes, seconds = (float(g) if g else 0.0 for g in wall.groups())
    return 3600 * hours + 60 * minutes + seconds, int(rss.group(1)) / 1024


def sense_ms(sequence: Path, sensor: str, seed: int, frames: int) -> float:
    """Milliseconds a frame of the model alone, images already decoded (what a study's worker adds)."""
    from longslam.io.sequence import SequenceReader
    from longslam.sim.sensors import frame_rng, get_sensor
    from longslam.sim.sensors.stream import camera_motions

    reader = SequenceReader(sequence)
    model = get_sensor(sensor)
    motions = camera_motions(reader.ground_truth)
    picks = np.linspace(0, len(reader) - 1, frames).astype(int)
    images = [(reader.read_rgb(i), reader.read_depth(i)) for i in picks]
    start = time.perf_counter()
    for i, (rgb, depth) in zip(picks, images):
        model.sense(rgb, depth, reader.intrinsics, motions[i], frame_rng(sensor, seed, int(i)))
    return 1000 * (time.perf_counter() - start) / frames


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--route", default="paper-300m")
    parser.add_argument("--noise", default="large")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--frames", type=int, default=200, help="frames for the model-alone figure")
    parser.add_argument("--sensors", nargs="+", default=["ideal", "kinect-v1", "realsense-d435"])
    parser.add_argument("--work", type=Path, help="folder for the sequences (default: a temporary one, removed)")
    args = parser.parse_args()

    work = args.work or Path(tempfile.mkdtemp(prefix="longslam-sensors-"))
    try:
        rows = []
        for sensor in args.sensors:
            out = work / f"{args.route}-{args.noise}-{args.seed}-{sensor}"
            wall, rss = timed_simulate(args.route, args.noise, args.seed, sensor, out)
            rows.append((sensor, wall, rss, sense_ms(out, sensor, args.seed, args.frames)))
        from longslam.io.sequence import SequenceReader

        frames = len(SequenceReader(work / f"{args.route}-{args.noise}-{args.seed}-{args.sensors[0]}"))
        base = rows[0][1]
        print(f"simulate --route {args.route} --noise {args.noise} --seed {args.seed} ({frames} frames), route rendered:")
        print("| sensor | wall [s] | x the first | peak RSS [MiB] | model alone [ms/frame] |")
        print("|---|---|---|---|---|")
        for sensor, wall, rss, ms in rows:
            print(f"| {sensor} | {wall:.1f} | {wall / base:.1f} | {rss:.0f} | {ms:.1f} |")
    finally:
        if args.work is None:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
