"""A sensor model applied on the fly to a sequence's clean frames, frame by frame and lazily: a
frame's images are made noisy only when a method first looks at them, from a generator of that
frame's own, so skipping frames (or starting late) changes no other frame."""

from __future__ import annotations

from collections.abc import Iterable, Iterator

import numpy as np

from longslam.core.errors import InputError
from longslam.core.frame import Frame
from longslam.core.registry import failure
from longslam.core.trajectory import Trajectory
from longslam.sim.image_contract import checked_images
from longslam.sim.sensors.base import FrameMotion, SensorModel, frame_rng


def camera_motions(truth: Trajectory) -> list[FrameMotion]:
    """Each frame's true angular and linear velocity in its camera frame, from the step to the
    next frame (the last frame takes the step before it)."""
    poses = np.asarray(truth.poses, dtype=np.float64)
    stamps = np.asarray(truth.timestamps, dtype=np.float64)
    n = len(poses)
    if n < 2:
        return [FrameMotion.still(float(t)) for t in stamps]
    rel = np.einsum("nji,njk->nik", poses[:-1, :3, :3], poses[1:, :3, :3])  # R_i^T R_{i+1}
    dt = np.maximum(np.diff(stamps), 1e-9)
    skew = 0.5 * np.stack(
        [rel[:, 2, 1] - rel[:, 1, 2], rel[:, 0, 2] - rel[:, 2, 0], rel[:, 1, 0] - rel[:, 0, 1]], axis=1
    )
    sin = np.linalg.norm(skew, axis=1)
    angle = np.arctan2(sin, np.clip((np.trace(rel, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0))
    scale = np.divide(angle, sin, out=np.ones_like(angle), where=sin > 1e-12)
    angular = skew * scale[:, None] / dt[:, None]
    moved = np.einsum("nji,nj->ni", poses[:-1, :3, :3], poses[1:, :3, 3] - poses[:-1, :3, 3])
    linear = moved / dt[:, None]
    angular = np.vstack([angular, angular[-1:]])
    linear = np.vstack([linear, linear[-1:]])
    return [FrameMotion(float(t), a, v) for t, a, v in zip(stamps, angular, linear)]


def _sense(sensor: SensorModel, frame: Frame, motion: FrameMotion, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The model's images of `frame`, checked. A model's code is a plugin's: what it raises
    (SystemExit and MemoryError too: a simulate that exited 0 having written nothing) or returns
    instead of two images is an InputError naming the sensor and the frame."""
    where = f"sensor {sensor.name!r}, frame {frame.index}"
    clean_rgb, clean_depth = frame.rgb, frame.depth  # read before: an error reading them is not the model's
    try:
        made = sensor.sense(clean_rgb, clean_depth, frame.intrinsics, motion, frame_rng(sensor.name, seed, frame.index))
    except (Exception, SystemExit) as err:
        raise InputError(f"{where}: sense() raised {failure(err)}") from None
    if not isinstance(made, (tuple, list)) or len(made) != 2:
        got = f"{len(made)} values" if isinstance(made, (tuple, list)) else f"a {type(made).__name__}"
        raise InputError(f"{where}: sense() returned {got}; expected (rgb, depth)")
    shape = (frame.intrinsics.height, frame.intrinsics.width)
    return checked_images(where, "sense()", *made, shape)


def sensed_frame(clean: Frame, sensor: SensorModel, seed: int, motion: FrameMotion) -> Frame:
    """`clean` as `sensor` delivers it (itself for the ideal sensor); its images made on first use."""
    if sensor.is_ideal:
        return clean
    made: list[tuple[np.ndarray, np.ndarray]] = []

    def both() -> tuple[np.ndarray, np.ndarray]:
        if not made:
            made.append(_sense(sensor, clean, motion, seed))
        return made[0]

    return Frame(clean.index, clean.timestamp, lambda: both()[0], lambda: both()[1], clean.odometry, clean.intrinsics)


def sensed_frames(
    frames: Iterable[Frame], sensor: SensorModel, seed: int, motions: list[FrameMotion]
) -> Iterator[Frame]:
    """Each frame as `sensor` delivers it; `motions` per frame index (from `camera_motions`)."""
    for frame in frames:
        if not 0 <= frame.index < len(motions):
            raise InputError(f"frame {frame.index} has no true camera motion ({len(motions)} frames of ground truth)")
        yield sensed_frame(frame, sensor, seed, motions[frame.index])
