"""Which RGB-D steps (`visual.py`) the front end trusts: the gates against the wheels, or
against the constant-velocity prediction where there are no wheels."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from longslam.core.frame import Frame
from longslam.core.geometry import wrap_angle
from longslam.slam.frontend.filter import BiasFilter
from longslam.slam.frontend.visual import TrackedAhead, VisualOdometry, VisualStep
from longslam.slam.graph.factors import WheelStep


@dataclass(frozen=True)
class GateBounds:
    """The gates of `FrontEndConfig` (its `visual_gate_*`, `visual_max_bias`,
    `visual_bias_reset_after`) and the forward-bias widening of its noise."""

    distance: float  # m, sideways (and forward when turning in place)
    angle: float  # rad
    sigmas: float  # forward gate in stds of the forward-bias innovation
    max_bias: float  # m per step between the RGB-D step and the raw wheel step
    reset_after: int  # consecutive forward refusals that widen the forward bias's variance
    bias_forward_reset: float  # m/frame: the std added then
    use_bias: bool  # the forward gate follows the bias's uncertainty only when it is estimated


class VisualGates:
    """The tracker's steps through the gates; counts go to the front end's `counts`
    (visual_accepted, visual_refused, visual_failed, forward_bias_resets). Without a tracker
    (visual steps off, or the front end on wheels alone) every call returns None."""

    def __init__(self, tracker: VisualOdometry | None, bounds: GateBounds, counts: dict[str, int]):
        self.tracker = tracker
        self.bounds = bounds
        self.counts = counts
        self._forward_refusals = 0

    def first(self, frame: Frame, sigma_w: float | None = None, ahead: TrackedAhead | None = None) -> None:
        """The first frame: the tracker keeps its image, there is no step yet."""
        if self.tracker is not None:
            self.tracker(frame.rgb, frame.depth, np.zeros(3), sigma_w=sigma_w, ahead=ahead)

    def against_wheels(
        self,
        frame: Frame,
        wheel: WheelStep,
        expected: np.ndarray,
        bias_variance: float,
        wheel_forward_variance: float,
        visual_forward_sigma: float,
        bias_filter: BiasFilter,
        sigma_w: float | None = None,
        ahead: TrackedAhead | None = None,
    ) -> VisualStep | None:
        """The RGB-D step if it agrees with the wheels: sideways and in heading within fixed gates
        of the bias-corrected wheel step `expected`; forward within `sigmas` stds of the forward
        bias's own uncertainty (a Mahalanobis gate), so the gate widens when the bias is unsure.

        The wheels' bias jumps to a new value every few seconds; a fixed gate around the old
        value would refuse all the evidence of the new one and leave the estimate metres off. So
        after `reset_after` consecutive forward refusals
        the filter's forward-bias variance is widened and the gate opens. A step fitted on noisy
        depth (`sigma_w`) is gated forward at its own forward std where that is the larger.
        `ahead`: the frame's tracks worked out ahead (`FrontEnd.work_ahead`).
        """
        g = self.bounds
        res = self._track(frame, expected, sigma_w, ahead)
        if res is None:
            return None
        d = res.step - expected
        if abs(d[1]) > g.distance or abs(wrap_angle(d[2])) > g.angle:
            return self._refused()
        if res.covariance is not None:
            visual_forward_sigma = max(visual_forward_sigma, float(np.sqrt(res.covariance[0, 0])))
        if wheel.moving:
            spread = np.sqrt(bias_variance + wheel_forward_variance + visual_forward_sigma**2)
            if (
                abs(d[0]) > max(g.sigmas * spread, g.distance)
                and g.use_bias
                or abs(res.step[0] - wheel.forward) > g.max_bias
            ):
                self._forward_refusals += 1
                if self._forward_refusals >= g.reset_after:
                    bias_filter.widen_forward_bias(g.bias_forward_reset)
                    self.counts["forward_bias_resets"] += 1
                    self._forward_refusals = 0
                return self._refused()
        elif abs(d[0]) > g.distance:
            return self._refused()
        self._forward_refusals = 0
        return self._accepted(res)

    def against_prediction(
        self,
        frame: Frame,
        expected: np.ndarray,
        gate_distance: float,
        gate_angle: float,
        ahead: TrackedAhead | None = None,
    ) -> VisualStep | None:
        """Without wheels: the RGB-D step fitted without starting from `expected` (RANSAC), if
        it lies within the gates of that prediction."""
        res = self._track(frame, None, ahead=ahead)
        if res is None:
            return None
        d = res.step - expected
        if np.hypot(d[0], d[1]) > gate_distance or abs(wrap_angle(d[2])) > gate_angle:
            return self._refused()
        return self._accepted(res)

    def _track(
        self, frame: Frame, start: np.ndarray | None, sigma_w: float | None = None, ahead: TrackedAhead | None = None
    ) -> VisualStep | None:
        if self.tracker is None:
            return None
        res = self.tracker(frame.rgb, frame.depth, start, sigma_w=sigma_w, ahead=ahead)
        if res is None:
            self.counts["visual_failed"] += 1
        return res

    def _refused(self) -> VisualStep | None:  # always None (no step): the gates return it as their answer
        self.counts["visual_refused"] += 1
        return None

    def _accepted(self, step: VisualStep) -> VisualStep:
        self.counts["visual_accepted"] += 1
        return step
