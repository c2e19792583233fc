"""Frames per second of the RGB-D camera on one core, at random poses along the university's corridors.

    python benchmarks/render_speed.py [--frames 300] [--threads 1] [--seed 0]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from longslam.core.geometry import camera_poses_from_planar
from longslam.sim.camera import CameraSettings, RGBDCamera
from longslam.world import get_world


def corridor_poses(world, n: int, seed: int, camera_height: float) -> np.ndarray:
    """Random (x, y, yaw) inside the corridors, kept 0.4 m off the walls."""
    rng = np.random.default_rng(seed)
    corridors = [r for r in world.plan.free if r.kind == "corridor"]
    lengths = np.array([max(r.size) for r in corridors])
    pick = rng.choice(len(corridors), n, p=lengths / lengths.sum())
    xyyaw = np.empty((n, 3))
    for i, k in enumerate(pick):
        r = corridors[k]
        xyyaw[i] = rng.uniform(r.xmin + 0.4, r.xmax - 0.4), rng.uniform(r.ymin + 0.4, r.ymax - 0.4), rng.uniform(-np.pi, np.pi)
    return camera_poses_from_planar(xyyaw, camera_height)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument("--threads", type=int, default=1, help="ray-casting threads (0: all cores)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    start = time.perf_counter()
    world = get_world("university")
    build_s = time.perf_counter() - start
    settings = CameraSettings()
    camera = RGBDCamera(world.mesh, settings, nthreads=args.threads)
    poses = corridor_poses(world, args.frames, args.seed, settings.camera_height)
    for pose in poses[:10]:  # warm-up
        camera.render(pose)
    start = time.perf_counter()
    for pose in poses:
        camera.render(pose)
    elapsed = time.perf_counter() - start
    mesh = world.mesh
    print(f"world: {len(mesh.triangles)} triangles, atlas {mesh.texture.shape[1]}x{mesh.texture.shape[0]} "
          f"({mesh.texture.nbytes / 1e6:.1f} MB), mesh {mesh.nbytes / 1e6:.1f} MB, built in {build_s:.2f} s")
    print(f"render {settings.width}x{settings.height}, threads={args.threads}: "
          f"{args.frames / elapsed:.1f} frames/s ({1000 * elapsed / args.frames:.1f} ms/frame)")


if __name__ == "__main__":
    main()
