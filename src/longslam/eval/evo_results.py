"""Result files that evo's `evo_res` (and `evo.tools.file_interface.load_res_file`) read, written
without evo (GPLv3, a test-only dependency of longslam).

evo's format (`file_interface.save_res_file`): a zip holding info.json (title, ref_name, est_name,
label), stats.json (rmse, mean, median, std, min, max, sse), one .npy per array (error_array,
timestamps, seconds_from_start, distances_from_start, distances, alignment_transformation_sim3)
and one TUM file per trajectory, named after it. The contents follow evo_ape / evo_rpe: the title
says the metric, relation, unit and alignment as evo words it, so `evo_res` shows longslam's
results beside evo's own and warns, as for its own, when two titles differ.
"""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import numpy as np

from longslam.core.trajectory import Trajectory
from longslam.eval.evaluation import Evaluation
from longslam.eval.metrics import DELTA_UNIT_LABELS, statistics  # evo's Unit values for frames, m, deg, rad
from longslam.eval.relations import EVO_NAMES, RELATION_UNITS
from longslam.io.atomic import atomic_path
from longslam.io.trajectory_files import format_tum


def _evo_unit(relation: str) -> str:
    return RELATION_UNITS[relation] or "unit-less"  # evo's Unit.none


def _alignment_note(evaluation: Evaluation) -> str:
    """The line evo_ape / evo_rpe add to a title for the alignment."""
    mode, n = evaluation.scores["align"], evaluation.scores["n_to_align"]
    note = {
        "se3": "\n(with SE(3) Umeyama alignment)",
        "sim3": "\n(with Sim(3) Umeyama alignment)",
        "scale": "\n(scale corrected)",
        "none": "\n(not aligned)",
        "origin": "\n(with origin alignment)",
    }[mode]
    if mode in ("se3", "sim3", "scale") and n != -1:
        note += f" (aligned poses: {n})"
    return note


def _stats(errors: np.ndarray) -> dict[str, float]:
    """evo's StatisticsType order (`metrics.statistics`), and sse as well, which evo_res shows."""
    return {**statistics(errors), "sse": float(np.sum(np.asarray(errors, dtype=np.float64) ** 2))}


def _write_zip(
    out: str | Path,
    info: dict,
    stats: dict,
    arrays: dict[str, np.ndarray],
    trajectories: dict[str, Trajectory],
    overwrite: bool,
) -> Path:
    out = Path(out)
    with atomic_path(out, overwrite=overwrite) as tmp:
        with zipfile.ZipFile(tmp, "w") as archive:
            archive.writestr("info.json", json.dumps(info))
            archive.writestr("stats.json", json.dumps(stats))
            for name, array in arrays.items():
                buffer = io.BytesIO()
                np.save(buffer, np.asarray(array))
                archive.writestr(f"{name}.npy", buffer.getvalue())
            for name, trajectory in trajectories.items():
                archive.writestr(f"{name}.tum", format_tum(trajectory).encode("utf-8"))
    return out


def save_ape_result(
    evaluation: Evaluation, out: str | Path, ref_name: str, est_name: str, overwrite: bool = False
) -> Path:
    """Write the APE of `evaluation` as `evo_ape --save_results` would."""
    relation = evaluation.scores["ape_pose_relation"]
    unit = _evo_unit(relation)
    info = {
        "title": f"APE w.r.t. {EVO_NAMES[relation]} ({unit})" + _alignment_note(evaluation),
        "ref_name": ref_name,
        "est_name": est_name,
        "label": f"APE ({unit})",
    }
    est = evaluation.aligned
    arrays = {
        "error_array": evaluation.ape_errors,
        "seconds_from_start": est.timestamps - est.timestamps[0],
        "timestamps": est.timestamps,
        "distances_from_start": evaluation.reference.distances(),
        "distances": est.distances(),
    }
    if evaluation.alignment_sim3 is not None:
        arrays["alignment_transformation_sim3"] = evaluation.alignment_sim3
    trajectories = {ref_name: evaluation.reference, est_name: est}
    return _write_zip(out, info, _stats(evaluation.ape_errors), arrays, trajectories, overwrite)


def save_rpe_result(
    evaluation: Evaluation, out: str | Path, ref_name: str, est_name: str, overwrite: bool = False
) -> Path:
    """Write the RPE of `evaluation` as `evo_rpe --save_results` would (pairs' poses only)."""
    from longslam.core.errors import TrajectoryError

    if evaluation.rpe_errors is None:
        raise TrajectoryError("no RPE to save: no pair of poses is delta apart (a path shorter than delta)")
    s = evaluation.scores
    relation = s["pose_relation"]
    unit = _evo_unit(relation)
    delta = s["rpe_delta"]
    title = (
        f"RPE w.r.t. {EVO_NAMES[relation]} ({unit})\nfor delta = {delta} ({DELTA_UNIT_LABELS[s['rpe_delta_unit']]})"
        + (" using all pairs" if s["rpe_all_pairs"] else " using consecutive pairs")
        + _alignment_note(evaluation)
    )
    info = {"title": title, "ref_name": ref_name, "est_name": est_name, "label": f"RPE ({unit})"}
    # As evo: the trajectories reduced to pose 0 and each pair's second pose; the arrays skip pose 0.
    ids = np.concatenate([[0], evaluation.rpe_ids]).astype(int)
    ref, est = evaluation.reference, evaluation.aligned
    ref_ids, est_ids = ref.poses[ids], est.poses[ids]
    arrays = {
        "error_array": evaluation.rpe_errors,
        "seconds_from_start": (est.timestamps[ids] - est.timestamps[ids][0])[1:],
        "timestamps": est.timestamps[ids][1:],
        "distances_from_start": _path(ref_ids)[1:],
        "distances": _path(est_ids)[1:],
    }
    if evaluation.alignment_sim3 is not None:
        arrays["alignment_transformation_sim3"] = evaluation.alignment_sim3
    trajectories = {}
    # All pairs repeat and reorder poses, which a TUM file (increasing stamps) cannot hold.
    if len(np.unique(ids)) == len(ids) and np.all(np.diff(ids) > 0):
        trajectories = {ref_name: ref.subset(ids), est_name: est.subset(ids)}
    return _write_zip(out, info, _stats(evaluation.rpe_errors), arrays, trajectories, overwrite)


def _path(poses: np.ndarray) -> np.ndarray:
    steps = np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(steps)])
