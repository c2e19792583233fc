"""Tiny synthetic sequences, written in a moment, for tests of the run machinery (the engine, run
folders, the CLI) that need frames but not a rendered building."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from longslam.core.frame import Intrinsics
from longslam.core.geometry import camera_poses_from_planar
from longslam.core.trajectory import Trajectory
from longslam.io.sequence import SequenceWriter

TINY_INTRINSICS = Intrinsics.from_fov(16, 12, 90.0)


def write_tiny_sequence(
    path: Path, n: int = 30, step: float = 0.15, turn: float = 0.0, odometry_scale: float = 1.0, seed: int = 0,
) -> tuple[Path, Trajectory, Trajectory]:
    """A 16 x 12 sequence of `n` frames at 10 Hz driving `step` m per frame (turning `turn` rad in
    all), with random images and depth, ground truth, and an odometry whose forward steps are
    scaled by `odometry_scale`. Returns (path, ground truth, odometry)."""
    rng = np.random.default_rng(seed)
    stamps = 0.1 * np.arange(n)
    xyyaw = np.column_stack([step * np.arange(n), np.zeros(n), np.linspace(0.0, turn, n)])
    truth = Trajectory(stamps, camera_poses_from_planar(xyyaw, 1.25))
    noisy = xyyaw.copy()
    noisy[:, 0] *= odometry_scale
    odometry = Trajectory(stamps, camera_poses_from_planar(noisy, 1.25))
    with SequenceWriter(path, TINY_INTRINSICS, 8.0, {"route": "tiny"}) as writer:
        for t in stamps:
            writer.add(t, rng.integers(0, 255, (12, 16, 3), dtype=np.uint8), rng.uniform(0.5, 4, (12, 16)).astype(np.float32))
        writer.set_ground_truth(truth)
        writer.set_odometry(odometry)
    return path, truth, odometry


def write_bag_sequence(path: Path) -> Path:
    """A tiny sequence that turns (24 frames), with noise level 'large' and the camera's height
    in its meta.json: what a bag's export needs to carry."""
    write_tiny_sequence(path, n=24, turn=1.0, odometry_scale=1.05)
    meta = json.loads((path / "meta.json").read_text())
    (path / "meta.json").write_text(json.dumps({**meta, "noise": "large", "camera": {"camera_height": 1.25}}))
    return path
