"""The one scorer: a trajectory against the ground truth. `longslam evaluate`, the demo, studies
and the benchmarks all score through here, so a figure means the same wherever it is printed.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from longslam.core.errors import InputError
from longslam.core.trajectory import Trajectory
from longslam.eval.evaluation import Evaluation, evaluate_full
from longslam.eval.metrics import MIN_STEP
from longslam.eval.sync import associate, associate_by_index
from longslam.io.trajectory_files import KITTI, read_trajectory
from longslam.run.folder import TRAJECTORY

BAG = "bag"  # the format read_source names for a bag topic

MAX_DIFF = 0.01  # seconds between matched stamps (the CLI's --max-diff default)


def _matched(
    truth: Trajectory, estimate: Trajectory, max_diff: float, by_index: bool, offset: float
) -> tuple[Trajectory, Trajectory]:
    """The pairs of poses that are scored, (truth's, estimate's): by index, or by timestamp.
    The scores and `coverage` pair the poses here, so the coverage speaks of the poses scored."""
    if by_index:
        return associate_by_index(truth, estimate)
    return associate(truth, estimate, max_diff=max_diff, offset=offset)


def score_full(
    truth: Trajectory,
    estimate: Trajectory,
    align: str | bool = "none",
    max_diff: float = MAX_DIFF,
    by_index: bool = False,
    what: str = "the estimate",
    min_step: float = MIN_STEP,
    offset: float = 0.0,
    **options: Any,
) -> Evaluation:
    """The evaluation behind `score`: its scores and the arrays (per-pose errors, the aligned
    estimate) that plots and result files need. `options` are `evaluate`'s keyword options."""
    ref, est = _matched(truth, estimate, max_diff, by_index, offset)
    with np.errstate(all="ignore"):  # overflow is reported below, as one error
        evaluation = evaluate_full(ref, est, align=align, min_step=min_step, **options)
    bad = [key for key, value in evaluation.scores.items() if isinstance(value, float) and not math.isfinite(value)]
    if bad:
        raise InputError(
            f"{what}: {', '.join(bad)} overflowed to NaN or infinity; "
            "the poses hold coordinates too large to score (expected metres)"
        )
    return evaluation


def score(truth: Trajectory, estimate: Trajectory, align: str | bool = "none", **options: Any) -> dict[str, Any]:
    """The paper's metrics and the field's (see `eval.evaluation.evaluate`) of `estimate` against
    `truth`: `score_full`'s scores, with its options (poses matched by timestamp, `max_diff` and
    `offset` in seconds as evo's --t_max_diff and --t_offset, or `by_index`). A metric that
    overflowed is an error: it measures nothing, and JSON could not hold it."""
    return score_full(truth, estimate, align, **options).scores


def trajectory_file(path: str | Path, names: tuple[str, ...]) -> Path:
    """A trajectory file, or the usual file inside a run or sequence folder."""
    path = Path(path)
    if path.is_dir():
        for name in names:
            if (path / name).is_file():
                return path / name
        raise InputError(f"{path} is a folder without {' or '.join(names)}")
    return path


# Below this share of matched poses (or of the ground truth's time span) `evaluate` warns: the
# figures then describe part of the route only.
COVERAGE_WARNING = 0.9


def _span(stamps: np.ndarray) -> float:
    return float(stamps[-1] - stamps[0]) if len(stamps) > 1 else 0.0


def coverage(
    truth: Trajectory, estimate: Trajectory, max_diff: float, by_index: bool, offset: float = 0.0
) -> dict[str, Any]:
    """How much of each trajectory the scores rest on: poses matched, their share of the
    estimate's poses, and the share of the ground truth's time span they cover."""
    ref, est = _matched(truth, estimate, max_diff, by_index, offset)
    truth_span = _span(truth.timestamps)
    return {
        "matched_poses": len(est),
        "matched_share_estimate": len(est) / len(estimate) if len(estimate) else 0.0,
        "matched_share_groundtruth_span": _span(ref.timestamps) / truth_span if truth_span > 0 else 1.0,
    }


def coverage_warnings(shares: dict[str, Any], poses: int, est_file: str, ref_file: str, max_diff: float) -> list[str]:
    """What `coverage` (of an estimate of `poses` poses) leaves doubtful, one warning each:
    evaluate's and diagnose's (a run diagnosed against a shorter sequence) check."""
    found = []
    if shares["matched_share_estimate"] < COVERAGE_WARNING:
        found.append(
            f"only {shares['matched_poses']} of {poses} poses of {est_file} "
            f"({shares['matched_share_estimate']:.0%}) have a ground-truth pose within {max_diff} s; "
            "the scores cover that part only"
        )
    if shares["matched_share_groundtruth_span"] < COVERAGE_WARNING:
        found.append(
            f"the matched poses cover {shares['matched_share_groundtruth_span']:.0%} of the time span "
            f"of {ref_file}; the scores cover that part of the route only"
        )
    return found


def _run_sequence_of(estimate: Path) -> str | None:
    """The sequence a run folder's stats.json says it ran on, if it says."""
    import json

    stats = estimate / "stats.json"
    if not estimate.is_dir() or not stats.is_file():
        return None
    try:
        value = json.loads(stats.read_text(encoding="utf-8")).get("sequence")
    except (OSError, ValueError, AttributeError):
        return None
    return value if isinstance(value, str) else None


def other_sequence_warning(run: str | Path, sequence: str | Path) -> str | None:
    """The warning for a run folder scored against another sequence than the one its stats.json
    names (`sequence`: a sequence folder, or a file in one), or None (the same one, or no run)."""
    own = _run_sequence_of(Path(run))
    if own is None:
        return None
    given = Path(sequence) if Path(sequence).is_dir() else Path(sequence).parent
    if Path(own).resolve() == given.resolve():
        return None
    return f"{run} ran on the sequence {own} (its stats.json), not on {given}"


STDIN = "-"  # a trajectory file name that means: TUM (or KITTI) text on standard input


def _is_camera_frame(frame: str) -> bool:
    return "cam" in frame.lower() or "optical" in frame.lower()


def body_frame_warning(
    est_frames: dict[str, str],
    est_format: str,
    est_file: str,
    ref_frames: dict[str, str],
    ref_format: str,
    ref_file: str,
) -> str | None:
    """A bag topic of a robot's body frame (an /odom of base_link) scored against camera poses
    (a TUM or KITTI file, longslam's, or a camera frame's topic): the fixed body-to-camera
    transform then enters every error, which reads as drift of the method."""
    sides = [(est_frames.get("child"), est_format, est_file), (ref_frames.get("child"), ref_format, ref_file)]
    for (frame, _, name), (other_frame, other_format, other_name) in (sides, sides[::-1]):
        if frame is None or _is_camera_frame(frame):
            continue
        camera = _is_camera_frame(other_frame) if other_frame is not None else other_format != BAG
        if camera:
            what = f"the camera frame {other_frame}" if other_frame else "camera poses"
            return (
                f"{name} holds poses of {frame} (its child_frame_id), {other_name} of {what}: the fixed transform "
                "between the two enters every error; score a topic of the camera's poses, or both of one frame"
            )
    return None


def read_source(
    source: str | Path,
    names: tuple[str, ...],
    topic: str | None = None,
    topic_option: str = "--topic",
    stdin_text: str | None = None,
    frames: dict[str, str] | None = None,
) -> tuple[Trajectory, str, str]:
    """A trajectory, its format (tum, kitti or bag) and a name for messages, from a file, a run
    or sequence folder, a ROS bag's topic, or `-` (stdin, given as `stdin_text` or read here).
    `frames` is told a bag topic's pose frame (see `read_bag_trajectory`)."""
    if str(source) == STDIN:
        if topic is not None:
            raise InputError(f"{topic_option} names a bag topic, but the trajectory comes from stdin (-)")
        if stdin_text is None:  # bounded: `evaluate - gt.txt < /dev/zero` read until MemoryError
            from longslam.io.trajectory_files import read_trajectory_text

            stdin_text = read_trajectory_text(Path("<stdin>"), getattr(sys.stdin, "buffer", sys.stdin), "<stdin>")
        trajectory, fmt = read_trajectory(Path("<stdin>"), text=stdin_text)
        return trajectory, fmt, "<stdin>"
    from longslam.io.rosbag.trajectory import is_bag

    if is_bag(source):
        from longslam.io.rosbag.trajectory import read_bag_trajectory

        trajectory = read_bag_trajectory(source, topic, topic_option, frames)
        return trajectory, BAG, trajectory.source
    if topic is not None:
        raise InputError(
            f"{topic_option} {topic}: {source} is not a ROS bag (a .bag or .mcap file, "
            "or a folder holding metadata.yaml)"
        )
    path = trajectory_file(source, names)
    trajectory, fmt = read_trajectory(path)
    return trajectory, fmt, str(path)


def score_files(*args: Any, **kwargs: Any) -> dict[str, Any]:
    """`score_files_full`'s scores (the same arguments)."""
    return score_files_full(*args, **kwargs).scores


def score_files_full(
    estimate: str | Path,
    truth: str | Path,
    align: str | bool = "none",
    max_diff: float = MAX_DIFF,
    min_step: float = MIN_STEP,
    warnings: list[str] | None = None,
    offset: float = 0.0,
    estimate_topic: str | None = None,
    truth_topic: str | None = None,
    **options: Any,
) -> Evaluation:
    """Score trajectory files (TUM or KITTI), run / sequence folders, topics of ROS bags or `-`
    (stdin, for one of the two). KITTI files have no stamps, so they are matched by index. The
    scores include how much was matched (`coverage`); what makes them doubtful (part of a route
    matched, a run scored against another sequence than its own) is appended to `warnings`.
    `options` are `evaluate`'s keyword options (pose_relation, delta, delta_unit...)."""
    if str(estimate) == STDIN and str(truth) == STDIN:
        raise InputError("only one of the estimate and the ground truth can come from stdin (-)")
    est_frames: dict[str, str] = {}
    ref_frames: dict[str, str] = {}
    est, est_format, est_file = read_source(estimate, (TRAJECTORY,), estimate_topic, "--est-topic", frames=est_frames)
    ref, ref_format, ref_file = read_source(truth, ("groundtruth.txt",), truth_topic, "--ref-topic", frames=ref_frames)
    by_index = KITTI in (est_format, ref_format)
    if by_index and offset != 0.0:
        raise InputError(
            f"--t-offset {offset}: {est_file if est_format == KITTI else ref_file} is a KITTI file, "
            "without timestamps, so poses are paired by index; drop --t-offset"
        )
    evaluation = score_full(
        ref,
        est,
        align,
        max_diff,
        by_index=by_index,
        what=f"{estimate} against {truth}",
        min_step=min_step,
        offset=offset,
        **options,
    )
    shares = coverage(ref, est, max_diff, by_index, offset)
    evaluation.scores.update(shares)
    if warnings is not None:
        warnings += coverage_warnings(shares, len(est), est_file, ref_file, max_diff)
        body = body_frame_warning(est_frames, est_format, est_file, ref_frames, ref_format, ref_file)
        if body is not None:
            warnings.append(body)
        if STDIN not in (str(estimate), str(truth)):
            other = other_sequence_warning(estimate, truth if Path(truth).is_dir() else ref_file)
            if other is not None:
                warnings.append(other)
    return evaluation
