"""What the fused front end works out from a frame's images alone, ahead of its step.

The engine decodes a fused method's next frames on a second thread (run/read_ahead.py), and runs
the method's `work_ahead` there too, in frame order, before `step` takes the frame. What is
worked out here depends on the images only: the depth's measured noise, the grey image, the
corners tracked into it from the frame before, and the scan (in the robot's frame, placed by the
camera mount that the first frame's odometry gives). So the step gets the numbers it would have
computed itself, and computes them itself for a frame nothing was worked out for (read without
the engine, or after a frame that was not worked out).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from longslam.core.frame import Frame, Intrinsics
from longslam.core.geometry import CameraMount
from longslam.slam.depth_trust import measured_noise, range_for_noise, too_noisy_for_scan, trusted_depth
from longslam.slam.frontend.scan import ScanExtractor
from longslam.slam.frontend.visual import CornerTracker, TrackedAhead, gray_image, near_mask

if TYPE_CHECKING:  # a type only: motion.py holds the front end that uses this module
    from longslam.slam.frontend.motion import FrontEndConfig


@dataclass(frozen=True)
class FrameAhead:
    """One frame as worked out ahead."""

    index: int
    previous: int | None  # the frame its corners were tracked from; None: not tracked ahead
    sigma_w: float | None  # the depth's measured noise (`measured_noise`)
    visual: TrackedAhead | None  # None without visual tracking
    mount: CameraMount  # the mount the scan was extracted at
    scan: tuple[np.ndarray, np.ndarray | None] | None  # (points, their range noise or None); None: not worked out

    def visual_after(self, stepped: int | None) -> TrackedAhead | None:
        """The visual part for a step whose previous frame was `stepped`: its tracks only if they
        start at that frame (the tracker keeps the image of the frame it saw last)."""
        if self.visual is None or self.previous == stepped:
            return self.visual
        return TrackedAhead(self.visual.gray, None, tracked=False)


class AheadWorker:
    """Works frames out on one thread, in order (`work`), for the step on another to `take`."""

    def __init__(self, intrinsics: Intrinsics, config: FrontEndConfig):
        self._config = config
        self._trust = config.depth_trust
        self._intrinsics = intrinsics
        self._corners = CornerTracker(intrinsics, config.visual_tracking) if config.visual else None
        # Placed at the first frame worked out, as the front end places its own at its first step.
        self._mount: CameraMount | None = None
        self._extract: ScanExtractor | None = None
        # (index, grey image, corner mask) of the frame worked out last, if the step tracks it as
        # exact depth: its corners are looked for within the mask, in the next frame's tracking.
        self._last: tuple[int, np.ndarray, np.ndarray] | None = None
        self._done: dict[int, FrameAhead] = {}

    def work(self, frame: Frame) -> FrameAhead:
        cfg, trust = self._config, self._trust
        if self._mount is None:
            self._mount = CameraMount.for_first_frame(frame.odometry, cfg.camera_height, cfg.default_camera_height)
            self._extract = ScanExtractor(self._intrinsics, self._mount.camera_in_base, cfg.scan)
        assert self._extract is not None  # made with the mount
        sigma_w = measured_noise(frame.depth, trust)
        limit = range_for_noise(sigma_w, trust)
        # Depth too noisy for a scan gives none, and is tracked with its noise in the step's own
        # masks: neither is worked out here.
        usable = not too_noisy_for_scan(limit, trust)
        trusted = np.asarray(trusted_depth(frame.depth, limit), dtype=np.float32) if usable else None
        scan: tuple[np.ndarray, np.ndarray | None] | None = None
        if trusted is not None:
            if limit is not None and trust.scan_columns:
                assert sigma_w is not None  # a limit comes from measured noise
                scan = self._extract.columns(
                    frame.depth, sigma_w, trust.column_returns, trust.column_max_sigma, trust.column_correlation
                )
            else:
                scan = (self._extract(trusted), None)
        visual, previous = None, None
        if self._corners is not None:
            gray = gray_image(frame.rgb)
            last, self._last = self._last, None
            tracks, tracked = None, False
            if trusted is not None:
                self._last = (frame.index, gray, near_mask(trusted, cfg.visual_tracking.max_range))
                if last is not None:
                    previous, tracks, tracked = last[0], self._corners(last[1], gray, last[2]), True
            visual = TrackedAhead(gray, tracks, tracked)
        ahead = FrameAhead(frame.index, previous, sigma_w, visual, self._mount, scan)
        self._done[frame.index] = ahead
        return ahead

    def take(self, index: int) -> FrameAhead | None:
        """Frame `index` as worked out, once; None if it was not."""
        return self._done.pop(index, None)
