"""A path follower like Habitat's ShortestPathFollower, in continuous time.

It turns in place when the path lies far off the heading, otherwise drives at up to the
linear speed while steering toward a look-ahead point (pure pursuit), and stops on each
waypoint. The pose is recorded at every tick of the camera rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from longslam.core.errors import InputError
from longslam.core.geometry import wrap_angle


@dataclass(frozen=True)
class FollowerSettings:
    linear_speed: float = 1.5  # m/s
    angular_speed_deg: float = 90.0  # deg/s
    rate_hz: float = 10.0  # camera frames per second
    turn_in_place_deg: float = 30.0  # heading error above which the robot turns on the spot
    lookahead: float = 0.6  # m
    goal_tolerance: float = 0.05  # m

    def __post_init__(self) -> None:
        for name in ("linear_speed", "angular_speed_deg", "rate_hz", "lookahead", "goal_tolerance"):
            if not getattr(self, name) > 0:
                raise InputError(f"follower setting {name} must be positive, got {getattr(self, name)}")


@dataclass
class DrivenPath:
    timestamps: np.ndarray  # (N,) s
    xyyaw: np.ndarray  # (N, 3) base pose on the floor
    waypoint_frames: list[int]  # frame index at which each waypoint was reached

    @property
    def length(self) -> float:
        return float(np.linalg.norm(np.diff(self.xyyaw[:, :2], axis=0), axis=1).sum())


class _Polyline:
    def __init__(self, xy: np.ndarray):
        self.xy = xy
        seg = np.diff(xy, axis=0)
        self.seg_len = np.linalg.norm(seg, axis=1)
        self.cum = np.concatenate([[0.0], np.cumsum(self.seg_len)])
        self.length = float(self.cum[-1])

    def point_at(self, s: float) -> np.ndarray:
        s = min(max(s, 0.0), self.length)
        i = int(np.clip(np.searchsorted(self.cum, s, side="right") - 1, 0, len(self.seg_len) - 1))
        f = 0.0 if self.seg_len[i] == 0 else (s - self.cum[i]) / self.seg_len[i]
        return self.xy[i] + f * (self.xy[i + 1] - self.xy[i])

    def project(self, p: np.ndarray, s_from: float, s_window: float) -> float:
        """Arc length of the closest point to p, searched forward from s_from only (no jumping back)."""
        lo = max(0, int(np.searchsorted(self.cum, s_from, side="right")) - 1)
        hi = int(np.searchsorted(self.cum, s_from + s_window, side="right")) + 1
        a, b = self.xy[lo:hi], self.xy[lo + 1 : hi + 1]
        n = min(len(a), len(b))
        a, b = a[:n], b[:n]
        d = b - a
        dd = np.maximum((d**2).sum(axis=1), 1e-12)
        f = np.clip(((p - a) * d).sum(axis=1) / dd, 0.0, 1.0)
        dist = np.linalg.norm(a + f[:, None] * d - p, axis=1)
        k = int(np.argmin(dist))
        return max(s_from, float(self.cum[lo + k] + f[k] * self.seg_len[lo + k]))


def follow_paths(
    paths: list[np.ndarray],
    settings: FollowerSettings = FollowerSettings(),
    max_frames: int = 10_000_000,
    progress: bool = False,
) -> DrivenPath:
    """Drive along consecutive polylines (each (N, 2) world metres), recording a pose per tick;
    `progress` shows a bar of the legs driven."""
    if not paths:
        raise InputError("a route needs at least two waypoints")
    dt = 1.0 / settings.rate_hz
    v_max = settings.linear_speed
    w_max = math.radians(settings.angular_speed_deg)
    turn_limit = math.radians(settings.turn_in_place_deg)

    first = paths[0]
    heading = first[min(len(first) - 1, 3)] - first[0]
    x, y = map(float, first[0])
    yaw = math.atan2(heading[1], heading[0]) if np.linalg.norm(heading) > 0 else 0.0
    poses = [(x, y, yaw)]
    reached = [0]
    from longslam.core.progress import bar

    for path in bar(paths, desc="driving the route", unit="leg", disable=not progress, leave=False):
        path = np.asarray(path, dtype=np.float64)
        if _already_there(path, (x, y), settings.goal_tolerance):  # a repeated waypoint, or one a few cm on
            reached.append(len(poses) - 1)
            continue
        line = _Polyline(path)
        s = 0.0
        while True:
            p = np.array([x, y])
            s = line.project(p, s, s_window=3.0)
            remaining = line.length - s
            to_goal = float(np.linalg.norm(line.xy[-1] - p))
            if remaining < settings.goal_tolerance and to_goal < settings.goal_tolerance * 2:
                break
            target = line.point_at(s + settings.lookahead)
            if np.linalg.norm(target - p) < 1e-6:
                target = line.xy[-1]
            bearing = math.atan2(target[1] - y, target[0] - x)
            error = float(wrap_angle(bearing - yaw))
            if abs(error) > turn_limit:
                v, w = 0.0, math.copysign(min(w_max, abs(error) / dt), error)
            else:
                # Pure pursuit: the arc through the look-ahead point sets the curvature.
                dist = max(float(np.linalg.norm(target - p)), 1e-6)
                curvature = 2.0 * math.sin(error) / dist
                v = min(v_max, max(to_goal, remaining) / dt)
                w = v * curvature
                if abs(w) > w_max:
                    v *= w_max / abs(w)
                    w = math.copysign(w_max, w)
            # Exact integration along a circular arc over the tick.
            if abs(w) > 1e-9:
                x += v / w * (math.sin(yaw + w * dt) - math.sin(yaw))
                y -= v / w * (math.cos(yaw + w * dt) - math.cos(yaw))
            else:
                x += v * dt * math.cos(yaw)
                y += v * dt * math.sin(yaw)
            yaw = float(wrap_angle(yaw + w * dt))
            poses.append((x, y, yaw))
            if len(poses) > max_frames:
                raise InputError(f"the follower did not reach a waypoint within {max_frames} frames")
        reached.append(len(poses) - 1)
    xyyaw = np.asarray(poses)
    return DrivenPath(np.arange(len(xyyaw)) * dt, xyyaw, reached)


def _already_there(path: np.ndarray, position: tuple[float, float], tolerance: float) -> bool:
    """A leg whose goal is within the goal tolerance of where the robot stands has nothing to
    drive (and a one-point path has no segment to follow)."""
    return len(path) < 2 or float(np.linalg.norm(path[-1] - np.asarray(position))) < tolerance
