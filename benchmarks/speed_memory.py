"""Whole-process speed and memory of `longslam run`, as a user meets them (issue 11's targets).

    python benchmarks/speed_memory.py [--route paper-300m] [--noise large] [--seed 0]
                                      [--variants odometry keyframe-wheel keyframe submap-wheel submap]

Each variant runs as its own `longslam run` process, one after the other: wall-clock time from
start to exit (imports, reading and writing included) and the process's peak resident memory as
the kernel counts it (`os.wait4`, the figure `/usr/bin/time -v` prints). From the run's own
samples: resident memory at 500 m and at the route's end, before `finish` (the growth target).
Variants: a method name, or NAME-wheel for the method on wheel odometry alone (the paper's
configuration).

Targets printed beside the figures: keyframe-wheel on paper-300m as fast as the real RTAB-Map
0.23.8 on this machine (16.1 s); every fused method >= 5x real time wall-clock; on paper-1km peak
keyframe <= 400 MB, submap <= 300 MB, growth from 500 m to the end <= 20 %.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

from common import run_process, sequence
from longslam.io.sequence import SequenceReader

RTABMAP_300M_WALL_S = 16.1  # the real RTAB-Map 0.23.8 on paper-300m large seed 0, this machine
FUSED_MIN_REAL_TIME = 5.0
PEAK_TARGET_MB = {"keyframe": 400, "submap": 300}
GROWTH_TARGET = 0.20


def rss_at(stats: dict, distance: np.ndarray, metres: float) -> float:
    """Resident MiB sampled at the frame where the route passes `metres` (its end if shorter)."""
    samples = np.array(stats["rss_samples"], dtype=np.float64)[:-1]  # the last is after finish
    frame = min(int(np.searchsorted(distance, metres)), len(distance) - 1)
    k = min(int(np.searchsorted(samples[:, 0], frame)), len(samples) - 1)
    return samples[k, 1] / 2**20


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--route", default="paper-300m")
    parser.add_argument("--noise", default="large")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--variants", nargs="+", default=["odometry", "keyframe-wheel", "keyframe", "submap-wheel", "submap"])
    parser.add_argument("--work", default="out/bench-speed-memory")
    args = parser.parse_args()
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    seq = sequence(work, args.route, args.noise, args.seed)
    reader = SequenceReader(seq)
    distance = reader.ground_truth.distances()
    duration = float(reader.timestamps[-1] - reader.timestamps[0])
    print(f"{seq.name}: {len(reader)} frames, {duration:.0f} s, {distance[-1]:.0f} m; {os.cpu_count()} cores")
    print(f"{'variant':15s} {'wall s':>7s} {'x real':>7s} {'peak MiB':>8s} {'at 500 m':>9s} {'at end':>7s} {'growth':>7s}  target")
    for variant in args.variants:
        method, _, frontend = variant.partition("-")
        command = [sys.executable, "-m", "longslam", "run", str(seq), "--method", method,
                   "--out", str(work / "runs" / f"{seq.name}-{variant}"), "--overwrite"]
        if frontend:
            command += ["--param", f"frontend.mode={frontend}"]
        wall, peak, status = run_process(command, work / f"{seq.name}-{variant}.log")
        if status:
            print(f"{variant:15s} failed (exit {status})")
            continue
        stats = json.loads((work / "runs" / f"{seq.name}-{variant}" / "stats.json").read_text())
        at_500, at_end = rss_at(stats, distance, 500.0), rss_at(stats, distance, distance[-1])
        growth = at_end / at_500 - 1.0
        targets = []
        if variant == "keyframe-wheel" and args.route == "paper-300m":
            targets.append(f"wall <= {RTABMAP_300M_WALL_S} s (RTAB-Map): {'met' if wall <= RTABMAP_300M_WALL_S else 'MISSED'}")
        if method != "odometry" and not frontend:
            ok = duration / wall >= FUSED_MIN_REAL_TIME
            targets.append(f">= {FUSED_MIN_REAL_TIME:.0f}x real time: {'met' if ok else 'MISSED'}")
        if args.route == "paper-1km" and method in PEAK_TARGET_MB and not frontend:
            # The targets are in MB (10^6 bytes); the kernel counts KiB.
            peak_mb = peak * 1024 * 1024 / 1e6
            ok = peak_mb <= PEAK_TARGET_MB[method]
            targets.append(f"peak {peak_mb:.0f} MB <= {PEAK_TARGET_MB[method]} MB: {'met' if ok else 'MISSED'}")
            targets.append(f"growth <= {GROWTH_TARGET:.0%}: {'met' if growth <= GROWTH_TARGET else 'MISSED'}")
        print(f"{variant:15s} {wall:7.1f} {duration / wall:7.1f} {peak:8.0f} {at_500:9.0f} {at_end:7.0f} {growth:7.1%}  "
              + "; ".join(targets))


if __name__ == "__main__":
    main()
