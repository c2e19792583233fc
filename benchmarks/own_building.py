"""Figures for a building of your own beside the university's: loading, render speed, and each
method's accuracy, memory and speed on a route through it.

    python benchmarks/own_building.py                                  # the test building (wing at 30 degrees)
    python benchmarks/own_building.py --route myroute.json --seeds 0 1 2 --compare demo
    python benchmarks/own_building.py --render-only                    # loading and render speed, seconds

Without --route, the generated test building (longslam.world.wing_building: a hall and a wing
at 30 degrees, written as GLB) is written to a temporary folder with a 49 m loop route through
it. --compare names a university route run the same way (default demo). Render speed is one
core's (Open3D given one thread) at the default 320 x 240 camera, along the route's ground truth.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from longslam.cli.demo import run_demo
from longslam.sim.camera import CameraSettings, RGBDCamera
from longslam.sim.drive import camera_trajectory, drive_route
from longslam.sim.routes import get_route
from longslam.world import load_world
from longslam.world.wing_building import write_loop_route


def test_building(folder: Path) -> Path:
    """The test building and a loop through it that drives the hall and the wing twice."""
    return write_loop_route(folder)


def render_speed(route_arg: str, frames: int = 300) -> tuple[float, dict]:
    start = time.perf_counter()
    route = get_route(route_arg)
    world = load_world(route.world)
    load_s = time.perf_counter() - start
    settings = CameraSettings()
    driven = drive_route(world, route)
    truth = camera_trajectory(driven.timestamps, driven.xyyaw, settings.camera_height, world.floor_z)
    camera = RGBDCamera(world.mesh, settings, nthreads=1)
    poses = truth.poses[np.linspace(0, len(truth) - 1, frames).astype(int)]
    camera.render(poses[0])
    start = time.perf_counter()
    for pose in poses:
        camera.render(pose)
    fps = frames / (time.perf_counter() - start)
    info = {"world": world.name, "triangles": len(world.mesh.triangles), "load_s": load_s, "route_m": driven.length,
            "frames": len(truth)}
    return fps, info


def methods_table(route_arg: str, noise: str, seeds: list[int], work: Path) -> dict[str, dict[str, list[float]]]:
    table: dict[str, dict[str, list[float]]] = {}
    for seed in seeds:
        rows, _ = run_demo(work / f"seed-{seed}", route_arg, noise, seed, progress=False)
        for row in rows:
            cells = table.setdefault(row["method"], {})
            for key in ("ate", "e_trans", "e_rot", "peak_rss_bytes", "real_time_factor"):
                cells.setdefault(key, []).append(float(row[key]))
    return table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--route", help="a route file whose world is your mesh (default: the test building's loop)")
    parser.add_argument("--compare", default="demo", help="a university route to run the same way (default demo)")
    parser.add_argument("--noise", default="large")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--work", help="folder for sequences and runs (default: a temporary folder)")
    parser.add_argument("--render-only", action="store_true", help="loading and render speed only, no methods")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        work = Path(args.work or tmp)
        route = args.route or str(test_building(work / "building"))
        print("| route | world | triangles | load + floor + grid [s] | route [m] | frames | render 320x240, 1 core [frames/s] |")
        print("|---|---|---|---|---|---|---|")
        for name in (route, args.compare):
            fps, info = render_speed(name)
            print(f"| {Path(name).stem} | {info['world']} | {info['triangles']} | {info['load_s']:.2f} | "
                  f"{info['route_m']:.1f} | {info['frames']} | {fps:.0f} |")
        if args.render_only:
            return
        print(f"\nnoise {args.noise}, seeds {' '.join(map(str, args.seeds))}: mean +- std\n")
        print("| route | method | ATE [m] | E_trans | E_rot [deg/m] | peak RSS [MB] | real-time factor |")
        print("|---|---|---|---|---|---|---|")
        for name in (route, args.compare):
            table = methods_table(name, args.noise, args.seeds, work / Path(name).stem)
            for method, cells in table.items():
                ate, et, er = (np.array(cells[k]) for k in ("ate", "e_trans", "e_rot"))
                print(f"| {Path(name).stem} | {method} | {ate.mean():.3f} +- {ate.std():.3f} | {et.mean():.4f} +- {et.std():.4f} | "
                      f"{er.mean():.4f} +- {er.std():.4f} | {np.mean(cells['peak_rss_bytes']) / 1e6:.0f} | "
                      f"{np.mean(cells['real_time_factor']):.1f} |")


if __name__ == "__main__":
    main()
