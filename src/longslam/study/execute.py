"""One run of a study, as a worker does it: frames in, method run, outputs written, scores made.

The worker reuses the route's rendered frames and draws the odometry for (noise level, seed) on
the fly, exactly as `longslam simulate` would write it, so a run matches `simulate` + `run`.
It returns a JSON-ready record that the parent stores in the results database.
"""

from __future__ import annotations

import json
import shutil
import socket
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from longslam.jsonable import json_default
from longslam.eval.align import alignment
from longslam.eval.map_quality import map_quality
from longslam.eval.metrics import ape_errors, ate, evaluate
from longslam.eval.sync import associate
from longslam.gridmap import GridMap
from longslam.io.atomic import atomic_path, name_final_folder
from longslam.io.sequence import SequenceReader
from longslam.pipeline import run_frames, write_result
from longslam.recording import frames_with_odometry, noisy_odometry
from longslam.sim.noise import get_noise
from longslam.slam.base import MethodContext, Result
from longslam.study.prepare import render_once
from longslam.study.spec import RunSpec
from longslam.trajectory import Trajectory

CURVE_POINTS = 600  # at most this many points of each curve (error, memory) are kept per run
RUN_FILES = {"trajectory": "trajectory.txt", "online": "online.txt", "grid": "grid.npz", "map": "map.ply", "stats": "stats.json"}

TruthLoader = Callable[[], tuple[GridMap, np.ndarray]]


def _json_default(value: Any) -> Any:
    # A record must always be written, so anything else is kept as its repr.
    try:
        return json_default(value)
    except TypeError:
        return repr(value)


def to_json(record: dict[str, Any]) -> str:
    """JSON text of a record; numpy values become numbers, anything else unknown its repr."""
    return json.dumps(record, default=_json_default)


def error_record(err: BaseException) -> dict[str, Any]:
    """The record of a run that raised."""
    return {
        "status": "error",
        "error": f"{type(err).__name__}: {err}",
        "traceback": "".join(traceback.format_exception(err)),
        "host": socket.gethostname(),
    }


def execute_run(spec: RunSpec, run_dir: str | Path, load_truth: TruthLoader | None = None, progress: bool = False) -> dict[str, Any]:
    """Do the run and write its folder `run_dir` (replacing an unfinished one). Returns its record.

    `load_truth` gives the world's ground-truth occupancy grid and the mask of observed walls;
    it is called only for a method that builds a grid, after the run (so not in its memory).
    """
    camera = spec.camera_settings()
    rendered = render_once(spec.route_object(), camera, spec.follower_settings())
    reader = SequenceReader(rendered)
    truth = reader.ground_truth
    assert truth is not None, "a rendered sequence always has ground truth"
    odometry = noisy_odometry(truth, get_noise(spec.noise), spec.seed, camera.camera_height)

    run_dir = Path(run_dir)
    if run_dir.exists():  # from a run whose record never reached the database
        shutil.rmtree(run_dir)
    run_dir.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(run_dir) as tmp:
        tmp.mkdir()
        context = MethodContext(reader.intrinsics, reader.max_depth, str(tmp))
        frames = frames_with_odometry(reader, odometry)
        result, figures = run_frames(spec.method_name, frames, context, spec.params, total=len(reader), progress=progress)
        figures.update(sequence=str(rendered), route=spec.route, noise=spec.noise, seed=spec.seed, label=spec.method)
        figures = name_final_folder(figures, tmp, run_dir)
        write_result(tmp, result, figures)
        record = score_run(spec, result, figures, truth, load_truth)
        record["files"] = {kind: name for kind, name in RUN_FILES.items() if (tmp / name).is_file()}
        (tmp / "record.json").write_text(to_json(record) + "\n")
    return record


def _thin(points: list[tuple[float, float]]) -> list[list[float]]:
    if len(points) <= CURVE_POINTS:
        return [list(map(float, p)) for p in points]
    idx = np.unique(np.linspace(0, len(points) - 1, CURVE_POINTS).round().astype(int))
    return [list(map(float, points[i])) for i in idx]


def score_run(
    spec: RunSpec,
    result: Result,
    figures: dict[str, Any],
    truth: Trajectory,
    load_truth: TruthLoader | None,
) -> dict[str, Any]:
    """Metrics, curves against distance travelled, and map quality of a finished run."""
    ref, est = associate(truth, result.trajectory)
    metrics = evaluate(ref, est, align=spec.align)
    ref_online, est_online = associate(truth, result.online)
    metrics["ate_online"] = ate(ref_online, est_online)

    travelled = truth.distances()
    at = np.clip(np.searchsorted(truth.timestamps, ref.timestamps), 0, len(truth) - 1)
    errors = ape_errors(ref, est, "translation")  # the ATE's per-pose term: no alignment
    error_curve = _thin(list(zip(travelled[at], errors)))
    memory_curve = _thin([(travelled[min(int(i), len(truth) - 1)], rss) for i, rss in figures["rss_samples"]])

    quality = None
    if result.grid is not None and load_truth is not None:
        grid, observed = load_truth()
        rotation, translation, scale = alignment(est, ref, spec.align)
        quality = map_quality(
            result.grid, grid, spec.map_tolerance_cells, observed,
            rotation, translation, scale, height=float(np.mean(est.positions[:, 2])),
        )
    summary = {k: v for k, v in figures.items() if k not in ("rss_samples",)}
    return {
        "status": "ok",
        "metrics": metrics,
        "map_quality": quality,
        "figures": summary,
        "error_curve": error_curve,
        "memory_curve": memory_curve,
        "host": socket.gethostname(),
    }
