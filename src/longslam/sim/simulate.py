"""The render cache and noisy sequences: rendered routes cached on disk, and noisy odometry.

Rendering is deterministic for a (world, route, camera, follower), so the frames are stored
once, as a TUM RGB-D sequence without odometry, under a key made from those settings. A
sequence for a (noise level, sensor, seed) is that rendering plus its own odometry, drawn per
frame by the noise model; with the ideal sensor its frames are hard links to the cached ones,
with any other the sensor model's output of them, written anew. Perturbations (frames dropped,
the lights dimmed...) act on the sensor model's output, so they too reuse the cached render.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from collections.abc import Iterator, Sequence
from dataclasses import asdict
from pathlib import Path

import numpy as np

import longslam
from longslam.core.errors import InputError
from longslam.core.frame import Frame
from longslam.core.geometry import camera_poses_from_planar, planar_from_camera_poses
from longslam.core.odometry_noise import BiasNoise
from longslam.core.progress import bar
from longslam.core.trajectory import Trajectory
from longslam.io.overwrite_policy import SEQUENCE, check_not_an_input, check_replaceable
from longslam.io.paths import check_output_folder
from longslam.io.sequence import SequenceReader, SequenceWriter, derive_sequence
from longslam.sim.camera import CameraSettings, RGBDCamera
from longslam.sim.drive import camera_trajectory, drive_route
from longslam.sim.follower import FollowerSettings
from longslam.sim.noise import apply_noise
from longslam.sim.perturbations import Perturbation, canonical
from longslam.sim.perturbations.stream import perturbed_frames
from longslam.sim.routes import Route
from longslam.sim.sensors import IDEAL, SensorModel, get_sensor
from longslam.sim.sensors.stream import camera_motions, sensed_frames
from longslam.world import load_world, world_key
from longslam.world.reference import MeshSpec, is_mesh_ref, world_identity

# Bump when rendering or driving changes in a way that makes cached frames stale.
RENDER_VERSION = 1


log = logging.getLogger(__name__)  # -v shows where frames come from (longslam/cli/output.py)


def cache_root() -> Path:
    """The render cache: LONGSLAM_CACHE, or ~/.cache/longslam if it is unset or empty (an empty
    value would otherwise put the cache in the current folder)."""
    given = os.environ.get("LONGSLAM_CACHE", "")
    root = Path(given) if given.strip() else Path.home() / ".cache" / "longslam"
    if root.exists() and not root.is_dir():
        raise InputError(
            f"LONGSLAM_CACHE={given}: {root} is a file; expected a folder for the render cache "
            "(or leave LONGSLAM_CACHE unset for ~/.cache/longslam)"
        )
    for parent in root.absolute().parents:
        if parent.exists():
            if not parent.is_dir():
                raise InputError(f"render cache {root}: {parent} is a file, so the cache cannot be made under it")
            break
    return root


def check_camera_in_world(world, camera: CameraSettings) -> None:
    """Refuse a camera mounted above the top of the building: it would render the roof."""
    top = float(np.max(world.mesh.vertices[:, 2])) - world.floor_z if len(world.mesh.vertices) else 0.0
    if camera.camera_height >= top:
        raise InputError(
            f"camera height {camera.camera_height:g} m is at or above the top of world {world.name!r} "
            f"({top:.2f} m above its floor): the camera would be over the ceiling"
        )


def cache_key(route: Route, camera: CameraSettings, follower: FollowerSettings) -> str:
    description = json.dumps(
        {
            "render_version": RENDER_VERSION,
            # A mesh world by its content, not its path: an edited mesh renders anew, a moved one does not.
            "world": world_identity(route.world),
            "waypoints": route.waypoints_json(),
            "camera": asdict(camera),
            "follower": asdict(follower),
        },
        sort_keys=True,
    )
    digest = hashlib.sha256(description.encode()).hexdigest()[:16]
    return f"{world_key(route.world)}-{route.name}-{digest}"


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
        log.info(
            "route %s at %d x %d: rendered frames from the cache, %s", route.name, camera.width, camera.height, path
        )
        return path
    log.info("route %s at %d x %d: rendering into the cache, %s", route.name, camera.width, camera.height, path)
    world = load_world(route.world)
    check_camera_in_world(world, camera)
    driven = drive_route(world, route, follower)
    root.mkdir(parents=True, exist_ok=True)  # once the route and camera are known to be good
    truth = camera_trajectory(driven.timestamps, driven.xyyaw, camera.camera_height, world.floor_z)
    renderer = RGBDCamera(world.mesh, camera)
    meta = {
        "world": route.world,
        "world_name": world.name,
        **({"mesh_floor_z": world.source_floor_z} if is_mesh_ref(route.world) else {}),  # moved to z = 0
        "route": route.name,
        "waypoints": route.waypoints_json(),
        "camera": asdict(camera),
        "follower": asdict(follower),
        "route_length_m": driven.length,
        "waypoint_frames": driven.waypoint_frames,
        "longslam_version": longslam.__version__,
    }
    with SequenceWriter(path, camera.intrinsics, camera.max_depth, meta, overwrite=True) as writer:
        frames = bar(
            range(len(truth)),
            desc=f"render {route.name} ({camera.width} x {camera.height})",
            unit="frame",
            disable=not progress,
            leave=False,
        )
        for i in frames:
            rgb, depth = renderer.render(truth.poses[i])
            writer.add(float(truth.timestamps[i]), rgb, depth)
        writer.set_ground_truth(truth)
    return path


# numpy's generators take any whole number from 0 up, but a study's database keeps the seed in an
# SQLite INTEGER (signed 64 bits): a larger seed would run, then fail to be recorded on every resume.
MAX_SEED = 2**63 - 1
SEED_RANGE = f"a whole number >= 0 and <= 2**63 - 1 = {MAX_SEED}"


def seed_problem(seed: object) -> str | None:
    """None for a seed every part of longslam can hold; else what is wrong with it."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        return f"expected {SEED_RANGE}, got {seed!r}"
    if not 0 <= int(seed) <= MAX_SEED:
        return f"{int(seed)} is out of range; expected {SEED_RANGE}"
    return None


def check_seed(seed: int, what: str = "seed") -> int:
    """The seed as an int, or InputError naming it; say so before any rendering."""
    problem = seed_problem(seed)
    if problem is not None:
        raise InputError(f"{what} {seed!r}: {problem}")
    return int(seed)


def noisy_odometry(truth: Trajectory, noise: BiasNoise, seed: int, camera_height: float) -> Trajectory:
    """Camera-in-world odometry poses for a ground-truth camera trajectory of a planar robot."""
    rng = np.random.default_rng(check_seed(seed))
    xyyaw = planar_from_camera_poses(truth.poses, camera_height)
    floor_z = float(truth.poses[0, 2, 3]) - camera_height
    noisy = apply_noise(noise, truth.timestamps, xyyaw, rng)
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
    sensor: SensorModel | str = IDEAL,
    perturbations: Sequence[Perturbation] = (),
) -> Path:
    """Write a sequence for (route, noise, sensor, perturbations, seed) to `out`, rendering the
    route only if not cached. The sensor model (a name or a model) and the perturbations (applied
    in order, after the sensor model) draw from the same seed as the odometry."""
    sensor = get_sensor(sensor) if isinstance(sensor, str) else sensor
    out = check_output_folder(out, "sequence folder")
    mesh = MeshSpec.from_ref(route.world).path if is_mesh_ref(route.world) else None
    check_not_an_input(out, {"mesh file": mesh, "render cache": cache_root()}, "sequence folder")
    check_replaceable(out, SEQUENCE, overwrite)
    check_seed(seed)
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
        sensor=sensor.name,
        sensor_model=sensor.describe(),
        longslam_version=longslam.__version__,
    )
    if perturbations:  # absent without them, so an unperturbed sequence's meta.json is unchanged
        meta.update(
            perturbation=canonical(perturbations),
            perturbations=[p.describe() for p in perturbations],
            frames_dropped=len(dropped_frames(reader, perturbations, seed)),
        )
    if sensor.is_ideal and not perturbations:
        derive_sequence(rendered, out, odometry, meta, overwrite=overwrite)
    else:
        write_sensed_sequence(
            reader,
            out,
            sensor,
            seed,
            odometry,
            meta,
            overwrite=overwrite,
            progress=progress,
            perturbations=perturbations,
        )
    return out


def dropped_frames(reader: SequenceReader, perturbations: Sequence[Perturbation], seed: int) -> list[int]:
    """The indices of the rendered frames the perturbations drop (decided without reading an image)."""
    truth = reader.ground_truth
    assert truth is not None, "a rendered sequence always has ground truth"
    kept = {f.timestamp for f in perturbed_frames(reader, perturbations, seed, truth.timestamps, camera_motions(truth))}
    return [i for i, t in enumerate(reader.timestamps) if float(t) not in kept]


def write_sensed_sequence(
    reader: SequenceReader,
    out: Path,
    sensor: SensorModel,
    seed: int,
    odometry: Trajectory,
    meta: dict,
    overwrite: bool = False,
    progress: bool = True,
    perturbations: Sequence[Perturbation] = (),
) -> None:
    """The rendered frames of `reader` as `sensor` delivers them, then perturbed, with `odometry`
    (every pose: a dropped frame is the camera's loss, not the wheels'), into `out`."""
    truth = reader.ground_truth
    assert truth is not None, "a rendered sequence always has ground truth"
    assert reader.max_depth is not None, "a rendered sequence always has a depth range"
    motions = camera_motions(truth)
    frames = sensed_frames(reader, sensor, seed, motions)
    if perturbations:
        frames = perturbed_frames(frames, perturbations, seed, truth.timestamps, motions)
    desc = f"sensor {sensor.name}" + (f", {canonical(perturbations)}" if perturbations else "")
    with SequenceWriter(out, reader.intrinsics, reader.max_depth, meta, overwrite=overwrite) as writer:
        for frame in bar(frames, total=len(reader), desc=desc, unit="frame", disable=not progress, leave=False):
            writer.add(frame.timestamp, frame.rgb, frame.depth)
        writer.set_ground_truth(truth)
        writer.set_odometry(odometry)


def frames_with_odometry(reader: SequenceReader, odometry: Trajectory) -> Iterator[Frame]:
    """The reader's frames with their odometry replaced, for noise applied on the fly."""
    if len(odometry) != len(reader):
        raise InputError(f"odometry has {len(odometry)} poses but sequence {reader.path} has {len(reader)} frames")
    for frame, pose in zip(reader, odometry.poses):
        frame.odometry = pose
        yield frame
