"""Figures for the foundation: render speed, simulate wall time, route lengths, dead-reckoning errors.

    python benchmarks/foundation.py [--seeds 5] [--skip-simulate]

Rendering is timed on one core (Open3D's ray caster given one thread). Simulating writes the
route's frames into a fresh cache folder so the time includes rendering and PNG encoding.
Dead reckoning is the `odometry` method, whose estimate is the odometry itself: its errors are
computed from the odometry drawn exactly as `longslam simulate` draws it.
"""

from __future__ import annotations

import argparse
import csv
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from longslam.eval.evaluation import evaluate
from longslam.sim.simulate import rendered_sequence
from longslam.sim.camera import CameraSettings, RGBDCamera
from longslam.sim.drive import camera_trajectory, drive_route
from longslam.core.odometry_noise import get_noise
from longslam.sim.routes import get_route
from longslam.sim.simulate import noisy_odometry
from longslam.world import get_world

PAPER = Path(__file__).resolve().parents[2] / "shared" / "reference" / "paper_accuracy.csv"


def render_speed(world, truth, frames: int = 300) -> float:
    camera = RGBDCamera(world.mesh, CameraSettings(), nthreads=1)
    poses = truth.poses[np.linspace(0, len(truth) - 1, frames).astype(int)]
    camera.render(poses[0])
    start = time.perf_counter()
    for pose in poses:
        camera.render(pose)
    return frames / (time.perf_counter() - start)


def paper_values() -> dict:
    values = {}
    if PAPER.exists():
        with PAPER.open() as f:
            rows = [line for line in f if not line.startswith("#")]
        for row in csv.DictReader(rows):
            values[(row["method"], row["route"], row["noise"], row["metric"])] = float(row["mean"])
    return values


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--skip-simulate", action="store_true", help="skip timing the full renders")
    args = parser.parse_args()

    world = get_world("university")
    print("== routes")
    truths = {}
    for name in ("demo", "paper-300m", "paper-1km"):
        route = get_route(name)
        start = time.perf_counter()
        driven = drive_route(world, route)
        plan_time = time.perf_counter() - start
        truths[name] = camera_trajectory(driven.timestamps, driven.xyyaw, CameraSettings().camera_height)
        print(
            f"{name:>11}: {len(route.waypoints)} waypoints, {driven.length:7.1f} m driven, "
            f"{len(driven.timestamps)} frames, {driven.timestamps[-1]:6.1f} s simulated (planned in {plan_time:.2f} s)"
        )

    print("\n== rendering (320 x 240, one core)")
    fps = render_speed(world, truths["paper-300m"])
    print(f"frames rendered per second: {fps:.1f} (target >= 50)")

    if not args.skip_simulate:
        print("\n== simulate (render + write PNGs), from an empty cache")
        for name in ("paper-300m", "paper-1km"):
            root = Path(tempfile.mkdtemp(prefix="longslam-bench-"))
            try:
                start = time.perf_counter()
                rendered_sequence(get_route(name), root=root, progress=False)
                wall = time.perf_counter() - start
            finally:
                shutil.rmtree(root, ignore_errors=True)
            simulated = truths[name].timestamps[-1]
            print(f"{name:>11}: {wall:6.1f} s wall for {simulated:6.1f} s simulated ({simulated / wall:.1f}x real time)")

    print(f"\n== dead reckoning on paper-300m, mean +- std over {args.seeds} seeds (paper: RTAB-Map / Voxgraph means)")
    paper = paper_values()
    truth = truths["paper-300m"]
    header = f"{'noise':>7} | {'ATE [m]':>14} | {'E_trans':>16} | {'E_rot [deg/m]':>16} | paper ATE R/V | paper E_trans R/V | paper E_rot R/V"
    print(header)
    print("-" * len(header))
    for level in ("small", "medium", "large", "xlarge"):
        scores = [evaluate(truth, noisy_odometry(truth, get_noise(level), seed, CameraSettings().camera_height)) for seed in range(args.seeds)]
        m = {k: (np.mean([s[k] for s in scores]), np.std([s[k] for s in scores])) for k in ("ate", "e_trans", "e_rot")}
        ref = lambda metric: "/".join(f"{paper.get((meth, '300m', level, metric), float('nan')):g}" for meth in ("rtabmap", "voxgraph"))
        print(
            f"{level:>7} | {m['ate'][0]:6.2f} +- {m['ate'][1]:5.2f} | {m['e_trans'][0]:.4f} +- {m['e_trans'][1]:.4f} | "
            f"{m['e_rot'][0]:.4f} +- {m['e_rot'][1]:.4f} | {ref('ate'):>13} | {ref('e_trans'):>17} | {ref('e_rot'):>15}"
        )


if __name__ == "__main__":
    main()
