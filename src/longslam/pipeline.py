"""Run one method over one sequence: feed the frames, time and measure it, write its outputs.

A run's folder holds `trajectory.txt` and `online.txt` (TUM), `stats.json`, and the method's maps
(`grid.npz`, `map.ply`). It is written under a temporary name and renamed when complete.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import shutil
import time
from collections.abc import Iterable
from pathlib import Path
from queue import Empty
from typing import Any

import numpy as np
from tqdm import tqdm

from longslam.errors import InputError
from longslam.eval.resources import current_rss_bytes, peak_rss_bytes
from longslam.frame import Frame
from longslam.io.atomic import atomic_path, name_final_folder, write_text
from longslam.io.partials import clean_stale_partials
from longslam.io.paths import check_output_folder
from longslam.jsonable import json_default
from longslam.io.sequence import SequenceReader
from longslam.io.trajectory_files import write_tum
from longslam.slam.base import MethodContext, Result
from longslam.slam.registry import create_method

RSS_SAMPLE_EVERY = 50  # frames between samples of resident memory


def run_frames(
    method_name: str,
    frames: Iterable[Frame],
    context: MethodContext,
    params: dict[str, Any] | None = None,
    total: int | None = None,
    progress: bool = True,
) -> tuple[Result, dict[str, Any]]:
    """Feed every frame to a new method and finish it. Returns its result and the harness's figures."""
    baseline_rss = current_rss_bytes()
    method = create_method(method_name, context, params)
    step_times: list[float] = []
    rss_samples: list[tuple[int, int]] = []
    first_t = last_t = None
    wall_start = time.perf_counter()
    count = 0
    for frame in tqdm(frames, total=total, desc=method_name, unit="frame", disable=not progress, leave=False):
        t0 = time.perf_counter()
        pose = method.step(frame)
        step_times.append(time.perf_counter() - t0)
        if np.shape(pose) != (4, 4):
            raise InputError(f"method {method_name!r} returned a pose of shape {np.shape(pose)} for frame {frame.index}; expected (4, 4)")
        if first_t is None:
            first_t = frame.timestamp
        last_t = frame.timestamp
        if count % RSS_SAMPLE_EVERY == 0:
            rss_samples.append((count, current_rss_bytes()))
        count += 1
    if count == 0:
        raise InputError("the sequence has no frames")
    t0 = time.perf_counter()
    result = method.finish()
    finish_time = time.perf_counter() - t0
    wall_time = time.perf_counter() - wall_start
    rss_samples.append((count, current_rss_bytes()))

    steps = np.array(step_times)
    method_time = float(steps.sum() + finish_time)
    duration = float(last_t - first_t) + (float(last_t - first_t) / max(count - 1, 1))
    figures = {
        "method": method_name,
        "params": dict(params or {}),
        "frames": count,
        "sequence_duration_s": duration,
        "wall_time_s": wall_time,
        "method_time_s": method_time,
        "finish_time_s": finish_time,
        "step_time_mean_s": float(steps.mean()),
        "step_time_p95_s": float(np.percentile(steps, 95)),
        "step_time_max_s": float(steps.max()),
        # Simulated seconds per second of the method's own processing (reading frames excluded).
        "real_time_factor": duration / method_time if method_time > 0 else float("inf"),
        "peak_rss_bytes": peak_rss_bytes(),
        "baseline_rss_bytes": baseline_rss,
        "rss_samples": rss_samples,
        "method_stats": result.stats,
    }
    return result, figures


def write_result(out: Path, result: Result, figures: dict[str, Any]) -> None:
    """Write a result's files into an existing folder."""
    write_tum(out / "trajectory.txt", result.trajectory)
    write_tum(out / "online.txt", result.online)
    if result.grid is not None:
        result.grid.save(out / "grid.npz")
    if result.cloud is not None and len(result.cloud):
        import open3d as o3d

        cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(result.cloud, dtype=np.float64)))
        o3d.io.write_point_cloud(str(out / "map.ply"), cloud)
    # The peak so far covers writing every other file (Open3D's import and the map included):
    # stats.json, written last, is tiny.
    figures["peak_rss_bytes"] = peak_rss_bytes()
    write_text(out / "stats.json", json.dumps(figures, indent=2, default=json_default) + "\n")


def run_sequence(
    method_name: str,
    sequence: str | Path,
    out: str | Path,
    params: dict[str, Any] | None = None,
    overwrite: bool = False,
    progress: bool = True,
    intrinsics: str | tuple[float, float, float, float] | None = None,
) -> dict[str, Any]:
    """Run a method over a sequence on disk and write the run folder `out`. Returns the figures.

    `intrinsics` (fx, fy, cx, cy) replace the sequence's camera.json or stand in for a missing one."""
    out = check_output_folder(out, "run folder")
    if (out.exists() or out.is_symlink()) and not overwrite:
        raise InputError(f"run folder {out} exists already; choose another path or pass --overwrite")
    reader = SequenceReader(sequence, intrinsics=intrinsics)
    clean_stale_partials(out.parent)  # run folders of runs that were killed
    # Without --overwrite the final rename refuses a folder another run finished meanwhile.
    with atomic_path(out, overwrite=overwrite) as tmp:
        tmp.mkdir(parents=True)
        context = MethodContext(reader.intrinsics, reader.max_depth, str(tmp))
        result, figures = run_frames(method_name, reader, context, params, total=len(reader), progress=progress)
        figures["sequence"] = str(Path(sequence).resolve())
        figures["intrinsics"] = {**reader.intrinsics.to_dict(), "source": reader.intrinsics_source}
        figures = name_final_folder(figures, tmp, out)
        write_result(tmp, result, figures)
    return figures


def _child(queue: mp.Queue, args: tuple, kwargs: dict) -> None:
    try:
        queue.put(("ok", run_sequence(*args, **kwargs)))
    except BaseException as err:  # reported to the parent, which re-raises
        queue.put(("error", f"{type(err).__name__}: {err}"))


def run_sequence_isolated(*args: Any, **kwargs: Any) -> dict[str, Any]:
    """`run_sequence` in a fresh process, so its peak memory is the run's alone."""
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    proc = ctx.Process(target=_child, args=(queue, args, kwargs))
    proc.start()
    # Poll rather than block: a child killed outright (out of memory, a signal) never reports.
    while True:
        try:
            status, payload = queue.get(timeout=1.0)
            break
        except Empty:
            if proc.is_alive():
                continue
            try:  # it may have reported just before it ended
                status, payload = queue.get(timeout=1.0)
                break
            except Empty:
                proc.join()
                raise RuntimeError(f"run failed in its process: it died with exit code {proc.exitcode} before reporting") from None
    proc.join()
    if status != "ok":
        raise RuntimeError(f"run failed in its process: {payload}")
    return payload
