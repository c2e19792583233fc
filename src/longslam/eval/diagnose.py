"""Where along a route a run's error comes from: heading, along-track and across-track parts, the
stretches that pick them up, the loop constraints against ground truth, and the factors each
stretch ran on.

Plain arrays in, plain dataclasses out: `longslam diagnose` (run/diagnose.py) reads the files,
`run/diagnose_plot.py` draws the result.

- The error at a frame is the estimate's planar pose against the truth's, unaligned (as the ATE
  is scored by default): the position error is split along and across the truth's heading, and
  the heading error is the estimate's yaw minus the truth's. A heading error of h degrees turns
  into an across-track error that grows by about sin(h) per metre driven, so a stretch that picks
  up heading explains the across-track error of every stretch after it.
- A stretch is a fixed length of route (by distance travelled along the truth); what it "picks up"
  is how much each part grows from its start to its end.
- The factors of a stretch come from the front end's table (frontend.csv): the share of frames
  whose scan registered, whose scan was refused, whose visual step was accepted, and how far the
  scans moved the prediction. Its dominant factor is, in this order: `loops` if a loop
  constraint has an end in it; `scans` if at least half of its frames registered a scan;
  `visual` if at least half took a visual step; else `wheels` (the frames ran on the wheels alone).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from longslam.core.geometry.planar import relative_xyyaw, wrap_angle

# A loop constraint further than this from the truth is wrong (the benchmarks' rule).
WRONG_LOOP_M = 0.5
WRONG_LOOP_DEG = 5.0
# A direction a constraint holds to a std over this (m) it does not hold: its error there is not
# the constraint's (keyframe's scan links leave the direction along a corridor free).
FREE_SIGMA_M = 1.0


@dataclass(frozen=True)
class ErrorParts:
    """Per frame: distance travelled along the truth, and the estimate's error against it."""

    distance_m: np.ndarray  # (N,)
    heading_deg: np.ndarray  # (N,) estimate's yaw minus the truth's, wrapped to (-180, 180]
    along_m: np.ndarray  # (N,) position error along the truth's heading (+ ahead)
    across_m: np.ndarray  # (N,) position error across it (+ to the left)

    @property
    def position_m(self) -> np.ndarray:
        return np.hypot(self.along_m, self.across_m)


def error_parts(truth_xyyaw: np.ndarray, estimate_xyyaw: np.ndarray) -> ErrorParts:
    """The error parts of (N, 3) planar poses against the truth's, frame by frame."""
    truth = np.asarray(truth_xyyaw, dtype=np.float64).reshape(-1, 3)
    estimate = np.asarray(estimate_xyyaw, dtype=np.float64).reshape(-1, 3)
    if truth.shape != estimate.shape:
        raise ValueError(f"truth has {len(truth)} poses, the estimate {len(estimate)}")
    d = estimate[:, :2] - truth[:, :2]
    c, s = np.cos(truth[:, 2]), np.sin(truth[:, 2])
    distance = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(truth[:, :2], axis=0), axis=1))])
    return ErrorParts(
        distance,
        np.degrees(wrap_angle(estimate[:, 2] - truth[:, 2])),
        d[:, 0] * c + d[:, 1] * s,
        -d[:, 0] * s + d[:, 1] * c,
    )


@dataclass(frozen=True)
class LoopError:
    frame_i: int
    frame_j: int
    error_m: float  # the constraint's translation against the truth's relative pose
    error_deg: float

    @property
    def wrong(self) -> bool:
        return self.error_m > WRONG_LOOP_M or self.error_deg > WRONG_LOOP_DEG


def held_translation_error(delta: np.ndarray, error_in_i: np.ndarray, information: np.ndarray) -> float:
    """The norm of a constraint's translation error (in frame i) without its part along the
    directions the constraint does not hold (std over `FREE_SIGMA_M`). `information` is in
    GTSAM's Pose2 tangent, the frame of j as the constraint places it."""
    c, s = np.cos(delta[2]), np.sin(delta[2])
    error = np.array([c * error_in_i[0] + s * error_in_i[1], -s * error_in_i[0] + c * error_in_i[1]])
    covariance = np.linalg.inv(information + 1e-12 * np.eye(3))[:2, :2]
    variances, directions = np.linalg.eigh(0.5 * (covariance + covariance.T))
    for variance, direction in zip(variances, directions.T):
        if variance > FREE_SIGMA_M**2:
            error = error - (error @ direction) * direction
    return float(np.hypot(error[0], error[1]))


def loop_errors(truth_xyyaw: np.ndarray, loops: np.ndarray) -> list[LoopError]:
    """Each loop constraint (rows of frame i, frame j, dx, dy, dyaw: frame j's base pose in frame
    i's; then, as loops.csv has them, the upper triangle of its information) against the truth's
    relative pose between the two frames. With the information, a direction the constraint does
    not hold does not count in its error."""
    truth = np.asarray(truth_xyyaw, dtype=np.float64)
    rows = np.asarray(loops, dtype=np.float64)
    rows = rows.reshape(-1, rows.shape[-1] if rows.ndim == 2 else 5)
    upper = np.triu_indices(3)
    out = []
    for row in rows:
        i, j, delta = int(row[0]), int(row[1]), row[2:5]
        d = delta - relative_xyyaw(truth[i], truth[j])
        error_m = float(np.hypot(d[0], d[1]))
        if len(row) >= 11:
            information = np.zeros((3, 3))
            information[upper] = row[5:11]
            information = information + np.triu(information, 1).T
            error_m = held_translation_error(delta, d[:2], information)
        out.append(LoopError(i, j, error_m, float(np.degrees(abs(wrap_angle(d[2]))))))
    return out


@dataclass(frozen=True)
class Stretch:
    start_m: float
    end_m: float
    region: str  # the room, corridor or hall most of its frames are in ("" if the world has no plan)
    heading_gain_deg: float  # |heading error| at the end minus at the start
    along_gain_m: float
    across_gain_m: float
    scan_share: float | None  # frames whose scan registered (None without a front-end table)
    scan_refused_share: float | None
    visual_share: float | None
    scan_shift_m: float | None  # how far the scans moved the prediction, summed
    loops: int  # loop constraints with an end in the stretch
    wrong_loops: int
    dominant: str  # loops, scans, visual or wheels (see the module's docstring); "" if unknown


def stretches(
    parts: ErrorParts,
    length_m: float,
    regions: list[str] | None = None,
    frame_table: dict[str, np.ndarray] | None = None,
    loops: list[LoopError] | None = None,
) -> list[Stretch]:
    """The route cut every `length_m` of distance travelled (the last stretch may be shorter).

    `regions` names each frame's place (see `regions_of`); `frame_table` holds the front end's
    columns by name (`wheel`, `visual`, `scan`, `scan_shift_m`), one row per frame."""
    if not length_m > 0:
        raise ValueError(f"a stretch must be longer than 0 m, got {length_m}")
    n = len(parts.distance_m)
    total = float(parts.distance_m[-1]) if n else 0.0
    edges = np.append(np.arange(0.0, total, length_m), total) if total > 0 else np.array([0.0, 0.0])
    out = []
    for start, end in zip(edges[:-1], edges[1:]):
        a = int(np.searchsorted(parts.distance_m, start, side="left"))
        b = max(a, int(np.searchsorted(parts.distance_m, end, side="right")) - 1)
        frames = slice(a, b + 1)
        region = ""
        if regions is not None:
            names, counts = np.unique(np.asarray(regions[a : b + 1], dtype=object).astype(str), return_counts=True)
            region = str(names[np.argmax(counts)]) if len(names) else ""
        shares: tuple[float | None, float | None, float | None, float | None] = (None, None, None, None)
        if frame_table is not None:
            scan = frame_table["scan"][frames]
            shares = (
                float(np.mean(scan > 0)),
                float(np.mean(scan < 0)),
                float(np.mean(frame_table["visual"][frames] > 0)),
                float(np.sum(frame_table["scan_shift_m"][frames])),
            )
        here = [lp for lp in (loops or []) if a <= lp.frame_i <= b or a <= lp.frame_j <= b]
        dominant = ""
        if here:
            dominant = "loops"
        elif frame_table is not None:
            assert shares[0] is not None and shares[2] is not None  # set from the front-end table above
            dominant = "scans" if shares[0] >= 0.5 else "visual" if shares[2] >= 0.5 else "wheels"
        out.append(
            Stretch(
                float(start),
                float(end),
                region,
                float(abs(parts.heading_deg[b]) - abs(parts.heading_deg[a])),
                float(abs(parts.along_m[b]) - abs(parts.along_m[a])),
                float(abs(parts.across_m[b]) - abs(parts.across_m[a])),
                *shares,
                len(here),
                sum(lp.wrong for lp in here),
                dominant,
            )
        )
    return out


def worst_stretches(found: list[Stretch], part: str, count: int = 3) -> list[Stretch]:
    """The `count` stretches that picked up most of `part` (heading, along or across)."""
    key = {"heading": "heading_gain_deg", "along": "along_gain_m", "across": "across_gain_m"}[part]
    return sorted((s for s in found if getattr(s, key) > 0), key=lambda s: -getattr(s, key))[:count]


def regions_of(xy: np.ndarray, rects: list) -> list[str]:
    """For each (x, y), the name (or kind) of the smallest free rectangle of a floor plan that
    holds it, doors left out where a room or corridor also holds the point; "" outside all."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    best = np.full(len(xy), np.inf)
    names = np.full(len(xy), "", dtype=object)
    for rect in rects:
        if rect.kind == "door":
            continue
        inside = (xy[:, 0] >= rect.xmin) & (xy[:, 0] <= rect.xmax) & (xy[:, 1] >= rect.ymin) & (xy[:, 1] <= rect.ymax)
        area = (rect.xmax - rect.xmin) * (rect.ymax - rect.ymin)
        take = inside & (area < best)
        best[take] = area
        names[take] = rect.name or rect.kind
    return [str(n) for n in names]
