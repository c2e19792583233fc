"""The building's wall directions as a heading reference: an optional structural prior.

Most buildings are drawn on a grid: their long walls are parallel or at right angles to each
other. A scan that sees a straight wall therefore measures the robot's heading modulo 90 degrees
against the walls seen at the start, with no loop closure, however far the route has gone. The
front end measures the dominant wall direction of a scan every few frames; the first `settle`
measurements, near the start, give the building's axes a first value (in the estimate's own
frame, so nothing about the world is assumed); each measurement within the gate of them then
corrects the online filter's heading, and in the final smoother ties its frame's heading to the
axes, a variable solved with the poses, so that a heading error while the axes settled is not
frozen into them.

A wall further than the gate from the axes (a wing built at 30 degrees) is not taken for one of
them: it gives no factor. The gate is `gate_deg` widened by `gate_sigmas` times the online
heading's std, so a heading that drifted where no wall was seen (a hall) is still caught.
Off by default: a building with no dominant grid, or a route through curved rooms, gets nothing
from it, and a wrong axis would pull every heading.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from longslam.core.errors import InputError
from longslam.core.geometry import fold_quarter as fold
from longslam.core.parameter import check_declared, param


@dataclass(frozen=True)
class WallAxesConfig:
    use: bool = param(False, "heading factors from the walls' directions in the final smoother")
    every: int = param(10, "frames between two measurements (one wall seen by many frames is one view)", at_least=1)
    neighbours: int = param(
        6, "scan points whose spread gives a point's local direction", at_least=2, why="a direction needs two points"
    )
    radius: float = param(0.25, "the neighbours' farthest distance", above=0, unit="m")
    straightness: float = param(
        0.05, "a neighbourhood's smaller over larger spread (eigenvalue) at most: a line", at_least=0, at_most=1
    )
    peak_width_deg: float = param(
        2.0, "a point's direction within this of the peak is along it", above=0, below=45, unit="deg"
    )
    min_points: int = param(40, "points along the peak direction a measurement needs", at_least=1)
    min_share: float = param(
        0.5, "share of the scan's straight points along the peak direction a measurement needs", at_least=0, at_most=1
    )
    settle: int = param(
        10, "measurements whose mean direction fixes the axes (one scan's can be a degree off)", at_least=1
    )
    gate_deg: float = param(
        3.0,
        "a wall direction further than this from the axes is not one of them (at most max_gate_deg)",
        above=0,
        below=45,
        unit="deg",
    )
    gate_sigmas: float = param(3.0, "the gate widened by this many of the online heading's stds", at_least=0)
    max_gate_deg: float = param(
        15.0, "the widened gate's limit: a wing at 30 degrees stays out", above=0, below=45, unit="deg"
    )
    sigma_deg: float = param(1.0, "heading std of one measurement in the final smoother", above=0, unit="deg")

    def __post_init__(self) -> None:
        check_declared(self, "front end", "wall_axes.")
        if self.gate_deg > self.max_gate_deg:
            raise InputError(
                f"front end: wall_axes.gate_deg must be at most max_gate_deg ({self.max_gate_deg}), got {self.gate_deg}"
            )


def wall_direction(scan_xy: np.ndarray, config: WallAxesConfig = WallAxesConfig()) -> tuple[float, int] | None:
    """The dominant direction (radians, modulo 90 degrees, in [-45, 45)) of the straight walls in
    a 2D scan (N, 2) and the number of points along it; None if no direction dominates."""
    pts = np.asarray(scan_xy, dtype=np.float64)
    if len(pts) < max(config.min_points, config.neighbours):
        return None
    dist, idx = cKDTree(pts).query(pts, k=config.neighbours, distance_upper_bound=config.radius)
    full = np.all(np.isfinite(dist), axis=1)
    if not np.any(full):
        return None
    near = pts[idx[full]]  # (M, k, 2)
    d = near - near.mean(axis=1, keepdims=True)
    cxx, cyy, cxy = (d[..., 0] ** 2).mean(1), (d[..., 1] ** 2).mean(1), (d[..., 0] * d[..., 1]).mean(1)
    half = np.sqrt(0.25 * (cxx - cyy) ** 2 + cxy**2)
    big, small = 0.5 * (cxx + cyy) + half, 0.5 * (cxx + cyy) - half
    straight = small <= config.straightness * np.maximum(big, 1e-12)
    if straight.sum() < config.min_points:
        return None
    along: np.ndarray = fold(0.5 * np.arctan2(2.0 * cxy[straight], (cxx - cyy)[straight]))
    # The peak of a 1-degree histogram (wrapping at +-45), then the points within peak_width of
    # it, averaged on the circle of 4 x angle (where 90 degrees apart is the same direction).
    bins = np.floor((np.degrees(along) + 45.0)).astype(int) % 90
    counts = np.bincount(bins, minlength=90)
    window = counts + np.roll(counts, 1) + np.roll(counts, -1)
    peak = math.radians(int(np.argmax(window)) + 0.5 - 45.0)
    members = np.abs(fold(along - peak)) <= math.radians(config.peak_width_deg)
    count = int(members.sum())
    if count < config.min_points or count < config.min_share * len(along):
        return None
    return mean_direction(along[members]), count


def mean_direction(angles: np.ndarray) -> float:
    """The mean of directions modulo 90 degrees (rad, in [-45, 45))."""
    a = np.asarray(angles, dtype=np.float64)
    return float(fold(math.atan2(np.sin(4.0 * a).sum(), np.cos(4.0 * a).sum()) / 4.0))


class WallAxes:
    """The building's axes, from the first measurements, and the heading each one gives."""

    def __init__(self, config: WallAxesConfig) -> None:
        self.config = config
        self.axes: float | None = None  # world direction of the walls, modulo 90 degrees (rad)
        self.measured = 0
        self.gated = 0  # measurements too far from the axes: another direction (a wing)
        self._settling: list[tuple[int, float, float]] = []  # (frame, yaw, wall direction in the robot's frame)

    def measure(
        self, frame: int, yaw: float, scan_xy: np.ndarray, yaw_std: float = 0.0
    ) -> list[tuple[int, float, float]]:
        """Walls along the axes, (frame, the heading in rad near that frame's yaw that puts them
        on the current axes, their direction in the robot's frame), that this frame's scan gives:
        none on a frame that does not measure or whose walls show no direction, or while the axes
        are settling; when they settle, the settling measurements' own."""
        cfg = self.config
        if frame % cfg.every:
            return []
        found = wall_direction(scan_xy, cfg)
        if found is None:
            return []
        self.measured += 1
        if self.axes is None:
            self._settling.append((frame, yaw, found[0]))
            if len(self._settling) < cfg.settle:
                return []
            worlds = np.array([fold(y + d) for _, y, d in self._settling])
            # The mean of the largest group within the gate of one of them: a wing or a box at an
            # angle among the settling measurements does not pull the axes.
            near = np.abs(fold(worlds[:, None] - worlds[None, :])) <= math.radians(cfg.gate_deg)
            self.axes = mean_direction(worlds[near[int(np.argmax(near.sum(axis=1)))]])
            settled, self._settling = self._settling, []
            return [f for f in (self._factor(k, y, d, 0.0) for k, y, d in settled) if f is not None]
        factor = self._factor(frame, yaw, found[0], yaw_std)
        return [] if factor is None else [factor]

    def _factor(self, frame: int, yaw: float, direction: float, yaw_std: float) -> tuple[int, float, float] | None:
        cfg = self.config
        gate = min(math.radians(cfg.gate_deg) + cfg.gate_sigmas * yaw_std, math.radians(cfg.max_gate_deg))
        assert self.axes is not None  # `measure` settles the axes before it asks for factors
        off = float(fold(yaw + direction - self.axes))
        if abs(off) > gate:
            self.gated += 1
            return None
        return frame, yaw - off, direction
