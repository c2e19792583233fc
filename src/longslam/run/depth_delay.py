"""Depth that is out of step with its colour by a known time, put back in step before a method sees
it: a camera whose two streams are not synchronised stamps both images of a frame alike, and every
method (longslam's and a plugin's) then lifts the colour's corners with depth seen from elsewhere."""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from typing import Any

import cv2
import numpy as np

from longslam.core.depth_warp import move_at_velocity, reproject_depth
from longslam.core.errors import InputError
from longslam.core.frame import Frame

# As the simulator's `depth-offset` perturbation: past half a second the held velocity means little.
MAX_DEPTH_DELAY_S = 0.5


def check_depth_delay(seconds: float, what: str = "--depth-delay") -> float:
    """`seconds` as a depth delay, or a one-line InputError naming `what`."""
    if not math.isfinite(seconds) or abs(seconds) > MAX_DEPTH_DELAY_S:
        raise InputError(
            f"{what}: {seconds!r} is not a delay; expected the seconds the depth lags the colour "
            f"(negative: leads), between -{MAX_DEPTH_DELAY_S:g} and {MAX_DEPTH_DELAY_S:g}"
        )
    return float(seconds)


def camera_move_over(
    previous: np.ndarray, current: np.ndarray, step_s: float, seconds: float
) -> tuple[np.ndarray, np.ndarray]:
    """(rotation, position) of a camera in itself as it was `seconds` earlier (a later self for
    negative seconds), moving at the velocity of the step from `previous` to `current`
    (camera-in-world poses `step_s` apart) held in its own axes (`move_at_velocity`)."""
    step = np.linalg.inv(previous) @ current
    turn = cv2.Rodrigues(np.ascontiguousarray(step[:3, :3]))[0].ravel()
    return move_at_velocity(turn, step[:3, 3], seconds / step_s)  # velocities per step, time in steps


def run_frames_in_step(frames: Iterable[Frame], seconds: float, source: str, about: dict[str, Any]) -> Iterator[Frame]:
    """`frames_in_step` for a run (`longslam run --depth-delay`, a study's `depth_delay`), with the
    delay recorded in what the run was given (`about`, its stats.json's `depth_delay_s`)."""
    about["depth_delay_s"] = seconds
    return frames_in_step(frames, seconds, source)


def frames_in_step(frames: Iterable[Frame], seconds: float, source: str) -> Iterator[Frame]:
    """`frames` with each depth image warped from where the camera was `seconds` before the frame's
    stamp (depth lagging the colour; negative: leading) to where it is at the stamp, by the
    odometry's move over the step on that side of the stamp: the step from the previous frame for a
    lag, the step to the next for a lead (so a lead holds each frame back until the next arrives).
    A frame without that step (the first, for a lag; the last, for a lead) keeps its depth. A
    frame's depth is warped when a method first reads it, so a method that reads one in ten frames'
    depth warps one in ten. `source` names the frames in errors (a frame without odometry)."""
    previous: Frame | None = None
    for frame in frames:
        if frame.odometry is None:
            raise InputError(f"{source}: frame {frame.index} has no odometry, which a depth delay needs")
        if seconds > 0:
            yield frame if previous is None else _moved_along(previous, frame, frame, seconds)
        elif previous is not None:
            yield _moved_along(previous, frame, previous, seconds)
        previous = frame
    if seconds <= 0 and previous is not None:
        yield previous


def _moved_along(first: Frame, second: Frame, frame: Frame, seconds: float) -> Frame:
    """`frame` (one of the two) with its depth moved by `seconds` of the step from `first` to `second`."""
    step_s = second.timestamp - first.timestamp
    if step_s <= 0:
        return frame
    assert first.odometry is not None and second.odometry is not None  # checked as they came
    return _with_depth_moved(frame, *camera_move_over(first.odometry, second.odometry, step_s, seconds))


def _with_depth_moved(frame: Frame, rotation: np.ndarray, position: np.ndarray) -> Frame:
    def depth() -> np.ndarray:
        return reproject_depth(np.asarray(frame.depth, dtype=np.float32), frame.intrinsics, rotation, position)

    return Frame(frame.index, frame.timestamp, lambda: frame.rgb, depth, frame.odometry, frame.intrinsics)
