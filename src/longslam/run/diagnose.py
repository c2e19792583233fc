"""`longslam diagnose RUN SEQ`: a run's error split into parts along the route, read from its
folder and its sequence (the maths is `eval/diagnose.py`, the picture `run/diagnose_plot.py`)."""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from longslam.core.errors import InputError
from longslam.core.geometry import planar_from_camera_poses
from longslam.core.timestamps import one_to_one_nearest
from longslam.eval.diagnose import (
    ErrorParts,
    LoopError,
    Stretch,
    error_parts,
    loop_errors,
    regions_of,
    stretches,
    worst_stretches,
)
from longslam.io.trajectory_files import read_trajectory
from longslam.run.folder import EVENTS, TRAJECTORY, read_events, read_table
from longslam.run.score import coverage_warnings, other_sequence_warning
from longslam.slam.api import Event
from longslam.world import load_world
from longslam.world.model import World

MAX_DIFF = 0.02  # s: a frame's ground-truth pose is the one within this of its stamp


@dataclass
class Diagnosis:
    run: str
    sequence: str
    parts: ErrorParts
    truth_xy: np.ndarray  # (N, 2) per matched frame
    estimate_xy: np.ndarray
    frames: np.ndarray  # (N,) the run's frame index of each matched pose
    stretches: list[Stretch]
    loops: list[LoopError]
    has_frontend_table: bool
    world: World | None
    # The run's events (events.csv: tracking lost, new maps, loops...), each with the region of
    # the building its first frame was in ("" without a world).
    events: list[tuple[Event, str]] = field(default_factory=list)
    # What makes the figures doubtful, as `evaluate` warns of it (a run of another sequence).
    warnings: list[str] = field(default_factory=list)

    def summary(self) -> dict[str, Any]:
        p = self.parts
        return {
            "frames": int(len(self.frames)),
            "route_m": float(p.distance_m[-1]),
            "final_position_error_m": float(p.position_m[-1]),
            "final_heading_error_deg": float(p.heading_deg[-1]),
            "final_along_m": float(p.along_m[-1]),
            "final_across_m": float(p.across_m[-1]),
            "max_position_error_m": float(p.position_m.max()),
            "max_abs_heading_error_deg": float(np.abs(p.heading_deg).max()),
            "ate_m": float(np.mean(p.position_m)),  # the paper's ATE (a mean), of the planar positions
            "loops": len(self.loops),
            "wrong_loops": sum(lp.wrong for lp in self.loops),
            "events": {
                kind: sum(1 for e, _ in self.events if e.kind == kind)
                for kind in sorted({e.kind for e, _ in self.events})
            },
        }

    def to_json(self) -> dict[str, Any]:
        return {
            "run": self.run,
            "sequence": self.sequence,
            "warnings": list(self.warnings),
            "summary": self.summary(),
            "units": {"distance": "m", "heading": "deg", "along": "m", "across": "m", "scan_shift": "m"},
            "stretches": [asdict(s) for s in self.stretches],
            "loops": [{**asdict(lp), "wrong": lp.wrong} for lp in self.loops],
            "events": [{**asdict(e), "region": region} for e, region in self.events],
            "picked_up_most": {
                part: [[s.start_m, s.end_m] for s in worst_stretches(self.stretches, part)]
                for part in ("heading", "along", "across")
            },
        }


def _camera_height(sequence: Path, run: Path) -> float:
    """The camera's height above the floor, which takes the camera poses to the robot's: from the
    sequence's meta.json, else the method's stats. Only z depends on it, not x, y or yaw."""
    for path, keys in (
        (sequence / "meta.json", ("camera", "camera_height")),
        (run / "stats.json", ("method_stats", "camera_height")),
    ):
        try:
            value: Any = json.loads(path.read_text(encoding="utf-8"))
            for key in keys:
                value = value[key]
            return float(value)
        except (OSError, ValueError, KeyError, TypeError):
            continue
    return 0.0


def _world_of(sequence: Path) -> World | None:
    """The simulated world the sequence was rendered in (for the plan and region names), if any."""
    try:
        ref = json.loads((sequence / "meta.json").read_text(encoding="utf-8"))["world"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    try:
        return load_world(ref)
    except InputError:
        return None


def diagnose_run(
    run: str | Path, sequence: str | Path, stretch_m: float = 50.0, max_diff: float = MAX_DIFF, with_world: bool = True
) -> Diagnosis:
    """Diagnose the run folder `run` against the sequence folder it ran on."""
    run, sequence = Path(run), Path(sequence)
    if not (run / TRAJECTORY).is_file():
        raise InputError(f"run folder {run} has no {TRAJECTORY}: expected the folder `longslam run --out` wrote")
    if not (sequence / "groundtruth.txt").is_file():
        raise InputError(f"sequence {sequence} has no groundtruth.txt: a diagnosis needs the ground truth")
    if not stretch_m > 0:
        raise InputError(f"--stretch {stretch_m}: expected a length in metres above 0")
    estimate, _ = read_trajectory(run / TRAJECTORY)
    truth, _ = read_trajectory(sequence / "groundtruth.txt")
    est_idx, ref_idx = one_to_one_nearest(estimate.timestamps, truth.timestamps, max_diff)
    if len(est_idx) < 2:
        raise InputError(
            f"{run / TRAJECTORY}: {len(est_idx)} poses have a ground-truth pose within {max_diff} s "
            f"in {sequence / 'groundtruth.txt'}; expected the run of that sequence"
        )
    height = _camera_height(sequence, run)
    est_planar = planar_from_camera_poses(estimate.poses[est_idx], height)
    truth_planar = planar_from_camera_poses(truth.poses[ref_idx], height)
    parts = error_parts(truth_planar, est_planar)
    # Tables index the run's frames; the truth of every frame (NaN where none matched) scores them.
    truth_by_frame = np.full((len(estimate), 3), np.nan)
    truth_by_frame[est_idx] = truth_planar
    loops: list[LoopError] = []
    if (run / "loops.csv").is_file():
        rows = read_table(run / "loops.csv").rows
        rows = (
            rows[
                np.all(np.isfinite(truth_by_frame[rows[:, 0].astype(int)]), axis=1)
                & np.all(np.isfinite(truth_by_frame[rows[:, 1].astype(int)]), axis=1)
            ]
            if len(rows)
            else rows
        )
        loops = loop_errors(truth_by_frame, rows)
    table = None
    if (run / "frontend.csv").is_file():
        read = read_table(run / "frontend.csv")
        by_frame = {int(f): k for k, f in enumerate(read.column("frame"))}
        keep = np.array([by_frame.get(int(i), -1) for i in est_idx])
        if np.all(keep >= 0):
            table = {name: read.column(name)[keep] for name in read.columns}
    # The tables speak of frames; the stretches of matched poses: map frames to positions.
    position_of = {int(f): k for k, f in enumerate(est_idx)}
    matched_loops = [
        LoopError(position_of[lp.frame_i], position_of[lp.frame_j], lp.error_m, lp.error_deg)
        for lp in loops
        if lp.frame_i in position_of and lp.frame_j in position_of
    ]
    world = _world_of(sequence) if with_world else None
    regions = regions_of(truth_planar[:, :2], world.plan.free) if world is not None and world.plan is not None else None
    found = stretches(parts, stretch_m, regions, table, matched_loops)
    events = read_events(run / EVENTS) if (run / EVENTS).is_file() else []
    placed = [
        (e, str(regions[position_of[e.first_frame]]) if regions is not None and e.first_frame in position_of else "")
        for e in events
    ]
    other = other_sequence_warning(run, sequence)  # evaluate's check: 71 m and +106 deg went by unremarked
    # evaluate's coverage check too: against a shorter sequence, the diagnosis covers its part only
    truth_span = float(truth.timestamps[-1] - truth.timestamps[0]) if len(truth) > 1 else 0.0
    matched = truth.timestamps[np.asarray(ref_idx)]
    matched_span = float(matched.max() - matched.min())
    shares = {
        "matched_poses": len(est_idx),
        "matched_share_estimate": len(est_idx) / len(estimate),
        "matched_share_groundtruth_span": matched_span / truth_span if truth_span > 0 else 1.0,
    }
    warned = coverage_warnings(
        shares, len(estimate), str(run / TRAJECTORY), str(sequence / "groundtruth.txt"), max_diff
    )
    return Diagnosis(
        str(run),
        str(sequence),
        parts,
        truth_planar[:, :2],
        est_planar[:, :2],
        np.asarray(est_idx),
        found,
        loops,
        table is not None,
        world,
        placed,
        ([other] if other else []) + warned,
    )


def diagnosis_text(d: Diagnosis) -> str:
    """The diagnosis as a terminal reads it: the summary, a line per stretch, the loops."""
    s = d.summary()
    lines = [
        f"{d.run} against {d.sequence}: {s['frames']} frames, {s['route_m']:.0f} m",
        f"  at the end: position error {s['final_position_error_m']:.3f} m (along {s['final_along_m']:+.3f} m, "
        f"across {s['final_across_m']:+.3f} m), heading {s['final_heading_error_deg']:+.2f} deg; "
        f"worst {s['max_position_error_m']:.3f} m and {s['max_abs_heading_error_deg']:.2f} deg; ATE {s['ate_m']:.3f} m",
        "",
        f"  {'stretch [m]':>13s}  {'region':14s} {'+heading':>9s} {'+along':>8s} {'+across':>8s} "
        f"{'scans':>6s} {'refused':>7s} {'visual':>6s} {'loops':>5s}  dominant",
        f"  {'':>13s}  {'':14s} {'[deg]':>9s} {'[m]':>8s} {'[m]':>8s} {'[%]':>6s} {'[%]':>7s} {'[%]':>6s} {'':>5s}",
    ]

    def pct(v: float | None) -> str:
        return "-" if v is None else f"{100 * v:.0f}"

    for st in d.stretches:
        loops = f"{st.loops}" + (f" ({st.wrong_loops} wrong)" if st.wrong_loops else "")
        lines.append(
            f"  {st.start_m:6.0f}-{st.end_m:6.0f}  {st.region[:14]:14s} {st.heading_gain_deg:+9.2f} "
            f"{st.along_gain_m:+8.3f} {st.across_gain_m:+8.3f} {pct(st.scan_share):>6s} "
            f"{pct(st.scan_refused_share):>7s} {pct(st.visual_share):>6s} {loops:>5s}  {st.dominant}"
        )
    lines.append("")
    for part, unit in (("heading", "deg"), ("along", "m"), ("across", "m")):
        worst = worst_stretches(d.stretches, part)
        key = {"heading": "heading_gain_deg", "along": "along_gain_m", "across": "across_gain_m"}[part]
        where = (
            ", ".join(
                f"{w.start_m:.0f}-{w.end_m:.0f} m {w.region} ({getattr(w, key):+.2f} {unit}, {w.dominant})"
                for w in worst
            )
            or "nowhere"
        )
        lines.append(f"  {part} error picked up most at: {where}")
    lines.append("")
    if not d.loops:
        lines.append("  loop constraints: none in loops.csv")
    else:
        wrong = [lp for lp in d.loops if lp.wrong]
        lines.append(
            f"  loop constraints: {len(d.loops)}, {len(wrong)} wrong (> 0.5 m, in the directions it holds, or > "
            "5 deg against the truth); "
            f"median error {np.median([lp.error_m for lp in d.loops]):.3f} m, "
            f"{np.median([lp.error_deg for lp in d.loops]):.2f} deg"
        )
        for lp in sorted(d.loops, key=lambda lp: -lp.error_m)[:10]:
            lines.append(
                f"    frames {lp.frame_i:6d} -> {lp.frame_j:6d}: {lp.error_m:.3f} m, {lp.error_deg:.2f} deg"
                + ("  WRONG" if lp.wrong else "")
            )
    lines += _events_text(d)
    if not d.has_frontend_table:
        lines.append("  (no frontend.csv in the run folder: the factor columns are empty)")
    return "\n".join(lines)


MOST_EVENTS_SHOWN = 20


def _events_text(d: Diagnosis) -> list[str]:
    if not d.events:
        return ["", "  events: none in events.csv (the method reports none, or nothing happened)"]
    counts = ", ".join(f"{n} {kind}" for kind, n in d.summary()["events"].items())
    lines = ["", f"  events: {counts}"]
    for event, region in d.events[:MOST_EVENTS_SHOWN]:
        frames = (
            f"frame {event.first_frame}"
            if event.first_frame == event.last_frame
            else f"frames {event.first_frame}-{event.last_frame}"
        )
        span = (
            f"{event.first_t:.1f} s"
            if event.first_frame == event.last_frame
            else f"{event.first_t:.1f}-{event.last_t:.1f} s"
        )
        lines.append(f"    {event.kind:14s} {frames:>17s}  {span:>15s}  {region or '-':14s} {event.detail}")
    if len(d.events) > MOST_EVENTS_SHOWN:
        lines.append(f"    ... {len(d.events) - MOST_EVENTS_SHOWN} more in events.csv")
    return lines
