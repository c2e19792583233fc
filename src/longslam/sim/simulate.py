"""Sequences with noisy odometry: the cached rendering plus odometry drawn per (noise level, seed)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np

import longslam
from longslam.errors import InputError
from longslam.frame import Frame
from longslam.geometry import camera_poses_from_planar, planar_from_camera_poses
from longslam.io.sequence import SequenceReader, derive_sequence
from longslam.sim.cache import rendered_sequence
from longslam.sim.camera import CameraSettings
from longslam.sim.follower import FollowerSettings
from longslam.sim.noise import BiasNoise
from longslam.sim.routes import Route
from longslam.trajectory import Trajectory


def noisy_odometry(truth: Trajectory, noise: BiasNoise, seed: int, camera_height: float) -> Trajectory:
    """Camera-in-world odometry poses for a ground-truth camera trajectory of a planar robot."""
    rng = np.random.default_rng(seed)
    xyyaw = planar_from_camera_poses(truth.poses, camera_height)
    floor_z = float(truth.poses[0, 2, 3]) - camera_height
    noisy = noise.apply(truth.timestamps, xyyaw, rng)
    return Trajectory(truth.timestamps, camera_poses_from_planar(noisy, camera_height, floor_z), source="odometry")


def simulate(
    route: Route,
    noise: BiasNoise,
    seed: int,
    out: str | Path,
    camera: CameraSettings = CameraSettings(),
    follower: FollowerSettings = FollowerSettings(),
    overwrite: bool = False,
    progress: bool = True,
) -> Path:
    """Write a sequence for (route, noise, seed) to `out`, rendering the route only if not cached."""
    out = Path(out)
    if out.exists() and not overwrite:
        raise InputError(f"output {out} exists already; choose another path or pass --overwrite")
    rendered = rendered_sequence(route, camera, follower, progress=progress)
    reader = SequenceReader(rendered)
    truth = reader.ground_truth
    assert truth is not None, "a rendered sequence always has ground truth"
    odometry = noisy_odometry(truth, noise, seed, camera.camera_height)
    meta = dict(reader.meta)
    meta.update(
        noise=noise.name,
        noise_linear_std=noise.linear_std,
        noise_angular_std_deg=noise.angular_std_deg,
        noise_redraw_period_s=noise.redraw_period,
        seed=seed,
        longslam_version=longslam.__version__,
    )
    derive_sequence(rendered, out, odometry, meta, overwrite=overwrite)
    return out


def frames_with_odometry(reader: SequenceReader, odometry: Trajectory) -> Iterator[Frame]:
    """The reader's frames with their odometry replaced, for noise applied on the fly."""
    if len(odometry) != len(reader):
        raise InputError(f"odometry has {len(odometry)} poses but sequence {reader.path} has {len(reader)} frames")
    for frame, pose in zip(reader, odometry.poses):
        frame.odometry = pose
        yield frame
