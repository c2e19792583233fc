"""Perturbations applied on the fly to the frames a sensor model delivers, frame by frame and
lazily: whether a frame is dropped is decided as it passes, its images are perturbed only when a
method first looks at them, each from a generator of that frame's own."""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence

import numpy as np

from longslam.core.errors import InputError
from longslam.core.frame import Frame
from longslam.core.registry import failure
from longslam.sim.image_contract import checked_images
from longslam.sim.perturbations.base import FrameContext, Perturbation, perturbation_rng
from longslam.sim.sensors.base import FrameMotion


def frame_context(frame: Frame, timestamps: np.ndarray, motions: Sequence[FrameMotion], seed: int) -> FrameContext:
    """What the perturbations know of `frame`, whose index is into `timestamps` and `motions`."""
    if not 0 <= frame.index < len(motions):
        raise InputError(f"frame {frame.index} has no true camera motion ({len(motions)} frames of ground truth)")
    return FrameContext(
        frame.index,
        float(frame.timestamp),
        float(timestamps[0]),
        float(timestamps[-1]),
        frame.intrinsics,
        motions[frame.index],
        int(seed),
        motions[frame.index - 1] if frame.index > 0 else None,
    )


def _perturb(
    perturbations: Sequence[Perturbation], frame: Frame, context: FrameContext
) -> tuple[np.ndarray, np.ndarray]:
    rgb, depth = frame.rgb, frame.depth  # read before: an error reading them is not a perturbation's
    shape = (frame.intrinsics.height, frame.intrinsics.width)
    for p in perturbations:
        if not p.changes_images:
            continue
        where = f"perturbation {p.text!r}, frame {frame.index}"
        try:
            made = p.perturb(rgb, depth, context, perturbation_rng(p.name, context.seed, context.index))
            rgb, depth = made
        except (Exception, SystemExit) as err:  # a plugin's code: what it raises or returns, named
            raise InputError(f"{where}: perturb() raised or returned other than (rgb, depth): {failure(err)}") from None
        rgb, depth = checked_images(where, "perturb()", rgb, depth, shape)
    return rgb, depth


def is_dropped(perturbations: Sequence[Perturbation], context: FrameContext) -> bool:
    """Whether any of the perturbations drops the frame (never the sequence's first)."""
    if context.timestamp <= context.start:
        return False
    for p in perturbations:
        if p.drops_frames:
            try:
                dropped = bool(p.drops(context, perturbation_rng(p.name, context.seed, context.index)))
            except (Exception, SystemExit) as err:
                raise InputError(
                    f"perturbation {p.text!r}, frame {context.index}: drops() raised {failure(err)}"
                ) from None
            if dropped:
                return True
    return False


def perturbed_frames(
    frames: Iterable[Frame],
    perturbations: Sequence[Perturbation],
    seed: int,
    timestamps: np.ndarray,
    motions: Sequence[FrameMotion],
) -> Iterator[Frame]:
    """The frames that get through, numbered anew from 0 (as a sequence written without the dropped
    ones reads back), each with its images perturbed on first use. `timestamps` and `motions` are
    per index of the rendered sequence (its ground truth's, and `camera_motions`')."""
    delivered = 0
    for frame in frames:
        context = frame_context(frame, timestamps, motions, seed)
        if is_dropped(perturbations, context):
            continue
        yield _perturbed_frame(frame, perturbations, context, delivered)
        delivered += 1


def _perturbed_frame(frame: Frame, perturbations: Sequence[Perturbation], context: FrameContext, index: int) -> Frame:
    if not any(p.changes_images for p in perturbations):
        if frame.index == index:
            return frame
        return Frame(index, frame.timestamp, lambda: frame.rgb, lambda: frame.depth, frame.odometry, frame.intrinsics)
    made: list[tuple[np.ndarray, np.ndarray]] = []

    def both() -> tuple[np.ndarray, np.ndarray]:
        if not made:
            made.append(_perturb(perturbations, frame, context))
        return made[0]

    return Frame(index, frame.timestamp, lambda: both()[0], lambda: both()[1], frame.odometry, frame.intrinsics)
