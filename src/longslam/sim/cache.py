"""Rendered routes cached on disk, so another noise level or seed never renders again.

Rendering is deterministic for a (world, route, camera, follower), so the frames are stored
once, as a TUM RGB-D sequence without odometry, under a key made from those settings.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import asdict
from pathlib import Path

from tqdm import tqdm

import longslam
from longslam.io.sequence import SequenceWriter
from longslam.sim.camera import CameraSettings, RGBDCamera
from longslam.sim.drive import camera_trajectory, drive_route
from longslam.sim.follower import FollowerSettings
from longslam.sim.routes import Route
from longslam.world import get_world

# Bump when rendering or driving changes in a way that makes cached frames stale.
RENDER_VERSION = 1


def cache_root() -> Path:
    return Path(os.environ.get("LONGSLAM_CACHE", Path.home() / ".cache" / "longslam"))


def cache_key(route: Route, camera: CameraSettings, follower: FollowerSettings) -> str:
    description = json.dumps(
        {
            "render_version": RENDER_VERSION,
            "world": route.world,
            "waypoints": [list(w) if not isinstance(w, str) else w for w in route.waypoints],
            "camera": asdict(camera),
            "follower": asdict(follower),
        },
        sort_keys=True,
    )
    digest = hashlib.sha256(description.encode()).hexdigest()[:16]
    return f"{route.world}-{route.name}-{digest}"


def rendered_sequence(
    route: Route,
    camera: CameraSettings = CameraSettings(),
    follower: FollowerSettings = FollowerSettings(),
    root: Path | None = None,
    progress: bool = True,
) -> Path:
    """Path of the route's rendered ground-truth sequence, rendering it first if it is not cached.

    The sequence is written under a temporary name and renamed when complete, so an interrupted
    render leaves nothing that a later call would take as cached.
    """
    root = Path(root) if root is not None else cache_root()
    path = root / cache_key(route, camera, follower)
    if path.is_dir():
        return path
    root.mkdir(parents=True, exist_ok=True)
    world = get_world(route.world)
    driven = drive_route(world, route, follower)
    truth = camera_trajectory(driven.timestamps, driven.xyyaw, camera.camera_height, world.floor_z)
    renderer = RGBDCamera(world.mesh, camera)
    meta = {
        "world": route.world,
        "route": route.name,
        "waypoints": [list(w) if not isinstance(w, str) else w for w in route.waypoints],
        "camera": asdict(camera),
        "follower": asdict(follower),
        "route_length_m": driven.length,
        "waypoint_frames": driven.waypoint_frames,
        "longslam_version": longslam.__version__,
    }
    with SequenceWriter(path, camera.intrinsics, camera.max_depth, meta, overwrite=True) as writer:
        frames = tqdm(range(len(truth)), desc=f"render {route.name}", unit="frame", disable=not progress, leave=False)
        for i in frames:
            rgb, depth = renderer.render(truth.poses[i])
            writer.add(float(truth.timestamps[i]), rgb, depth)
        writer.set_ground_truth(truth)
    return path
