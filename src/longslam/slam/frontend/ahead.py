"""What the fused front end works out from a frame's images alone, ahead of its step.

The engine decodes a fused method's next frames on a second thread (run/read_ahead.py), and runs
the method's `work_ahead` there too, in frame order, before `step` takes the frame. What is
worked out here depends on the images only: the depth's measured noise, the grey image, and the
corners tracked into it from the frame before. So the step gets the numbers it would have
computed itself, and computes them itself for a frame nothing was worked out for (read without
the engine, or after a frame that was not worked out).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from longslam.core.frame import Frame, Intrinsics
from longslam.slam.depth_trust import DepthTrust, measured_noise, range_for_noise, too_noisy_for_scan, trusted_depth
from longslam.slam.frontend.visual import CornerTracker, TrackedAhead, VisualConfig, gray_image, near_mask


@dataclass(frozen=True)
class FrameAhead:
    """One frame as worked out ahead."""

    index: int
    previous: int | None  # the frame its corners were tracked from; None: not tracked ahead
    sigma_w: float | None  # the depth's measured noise (`measured_noise`)
    trusted: np.ndarray  # the depth within the range that noise allows (`trusted_depth`)
    visual: TrackedAhead | None  # None without visual tracking

    def visual_after(self, stepped: int | None) -> TrackedAhead | None:
        """The visual part for a step whose previous frame was `stepped`: its tracks only if they
        start at that frame (the tracker keeps the image of the frame it saw last)."""
        if self.visual is None or self.previous == stepped:
            return self.visual
        return TrackedAhead(self.visual.gray, None, tracked=False)


class AheadWorker:
    """Works frames out on one thread, in order (`work`), for the step on another to `take`."""

    def __init__(self, intrinsics: Intrinsics, trust: DepthTrust, visual: VisualConfig | None):
        self._trust = trust
        self._corners = None if visual is None else CornerTracker(intrinsics, visual)
        self._max_range = 0.0 if visual is None else visual.max_range
        # (index, grey image, corner mask) of the frame worked out last, if the step tracks it as
        # exact depth: its corners are looked for within the mask, in the next frame's tracking.
        self._last: tuple[int, np.ndarray, np.ndarray] | None = None
        self._done: dict[int, FrameAhead] = {}
        # Index of the frame the step took last: written by the step's thread, read here.
        self.stepped: int | None = None

    def work(self, frame: Frame) -> FrameAhead:
        sigma_w = measured_noise(frame.depth, self._trust)
        limit = range_for_noise(sigma_w, self._trust)
        trusted = trusted_depth(frame.depth, limit)
        visual, previous = None, None
        if self._corners is not None:
            gray = gray_image(frame.rgb)
            last, self._last = self._last, None
            tracks, tracked = None, False
            # Depth too noisy for a scan is tracked with its noise, in other masks: the step's.
            if not too_noisy_for_scan(limit, self._trust):
                mask = near_mask(np.asarray(trusted, dtype=np.float32), self._max_range)
                self._last = (frame.index, gray, mask)
                if last is not None and not self._step_waits_for(frame.index):
                    previous, tracks, tracked = last[0], self._corners(last[1], gray, last[2]), True
            visual = TrackedAhead(gray, tracks, tracked)
        ahead = FrameAhead(frame.index, previous, sigma_w, trusted, visual)
        self._done[frame.index] = ahead
        return ahead

    def _step_waits_for(self, index: int) -> bool:
        """Whether the step has caught up: it took the frame before `index` and waits for this
        one. Tracking is the costly part of the work, so it is then left to the step, and the two
        threads share it as their pace allows (a light step, the keyframe method's, would
        otherwise wait for this thread). Either thread tracks to the same numbers."""
        stepped = self.stepped
        return stepped is not None and index - stepped <= 1

    def take(self, index: int) -> FrameAhead | None:
        """Frame `index` as worked out, once; None if it was not."""
        return self._done.pop(index, None)
