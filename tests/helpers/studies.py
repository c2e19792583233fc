"""What the study tests run: a tiny route, a plugin of test methods registered through the
`longslam.methods` entry point (one with a grid, one that raises, one whose process dies, slow ones),
a study file over them, and the headless browser the report is opened in."""

from __future__ import annotations

import json
import shutil
import textwrap
from pathlib import Path

ROUTE = "20 31.25\n28 31.25\n"  # 8 m along the spine: about 55 frames

PLUGIN = '''
"""Test methods registered through the `longslam.methods` entry point, like a user's own."""
import os
import signal
import time

import numpy as np

from longslam.core.geometry import base_to_camera, planar_from_camera_poses
from longslam.slam.api import MethodSpec, Result
from longslam.slam.occupancy import assemble, local_grid
from longslam.core.trajectory import Trajectory


class Gridded:
    """Dead reckoning plus an occupancy grid from every 5th depth image."""

    name = "gridded"

    def __init__(self, context, params):
        self.stamps, self.poses, self.grids = [], [], []

    def step(self, frame):
        pose = np.array(frame.odometry, dtype=np.float64)
        self.stamps.append(frame.timestamp)
        self.poses.append(pose)
        if frame.index % 5 == 0:
            self.grids.append((len(self.poses) - 1, local_grid(frame.depth, frame.intrinsics, base_to_camera(1.25))))
        return pose

    def finish(self):
        trajectory = Trajectory(np.array(self.stamps), np.array(self.poses))
        xyyaw = planar_from_camera_poses(trajectory.poses, 1.25)
        grid = assemble([g for _, g in self.grids], xyyaw[[i for i, _ in self.grids]])
        return Result(trajectory, trajectory, grid=grid, stats={"local_grids": len(self.grids)})


class Crashy(Gridded):
    def step(self, frame):
        if frame.index == 5:
            raise RuntimeError("crashy fails on purpose at frame 5")
        return super().step(frame)


class Dies(Gridded):
    def step(self, frame):
        if frame.index == 5:
            # What a native system says as it dies goes to the run's console.log.
            os.write(1, b"native: assertion failed, about to die\\n")
            os.kill(os.getpid(), signal.SIGKILL)
        return super().step(frame)


class Sleepy(Gridded):
    """Slow enough that two runs started together overlap."""

    def step(self, frame):
        time.sleep(0.02)
        return super().step(frame)


# A system with threads of its own, as ORB-SLAM3's plugin declares itself.
HOG = MethodSpec("hog", None, Sleepy, threads=2, real_time=True, deterministic=False)
'''


def write_study(
    root: Path, name: str, methods: list[str], noise: list[str], seeds: list[int], extra: str = ""
) -> Path:
    """NAME.toml in `root` over the route tiny.txt there: `methods` at `noise` over `seeds` with a
    64 x 48 camera, plus `extra` lines (an axis, a depth_delay)."""
    path = root / f"{name}.toml"
    path.write_text(textwrap.dedent(f"""
        name = "{name}"
        routes = ["tiny.txt"]
        noise = {json.dumps(noise)}
        methods = {json.dumps(methods)}
        seeds = {json.dumps(seeds)}
    """) + (f"{extra}\n" if extra else "") + "[camera]\nwidth = 64\nheight = 48\n")
    return path


def chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


def tiny_study_file(folder: Path, seeds: str, extra: str = "", name: str = "s.toml") -> Path:
    """A study file (and its 1 m route r.txt) in `folder`: odometry at noise 'none' with a 16 x 12
    camera over `seeds` (TOML text), plus `extra` lines."""
    (folder / "r.txt").write_text("20 31.25\n21 31.25\n")
    study = folder / name
    study.write_text(f'routes = ["r.txt"]\nnoise = ["none"]\nmethods = ["odometry"]\nseeds = {seeds}\n'
                     '[camera]\nwidth = 16\nheight = 12\n' + extra)
    return study


def empty_study_folder(path: Path) -> Path:
    """A study folder whose database holds a study and no runs."""
    from longslam.study.database import DB_NAME, ResultsDB

    path.mkdir()
    with ResultsDB(path / DB_NAME) as db:
        db.set_study({"name": "s", "routes": [], "noise": [], "methods": [], "seeds": [0]})
    return path


AXIS_STUDY = """
routes = ["tiny.txt"]
noise = ["large"]
methods = ["odometry"]
seeds = 2
{extra}
[camera]
width = 64
height = 48
"""


def axis_study_file(folder: Path, extra: str = "") -> Path:
    """study.toml in `folder` (and its 8 m route tiny.txt): odometry at large noise, seeds 0-1, a 64 x 48
    camera, plus `extra` lines (an axis, a depth_delay): for tests that plan runs without running them."""
    (folder / "tiny.txt").write_text(ROUTE)
    path = folder / "study.toml"
    path.write_text(AXIS_STUDY.format(extra=extra))
    return path

