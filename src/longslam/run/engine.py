"""The run engine: feed frames to a method, time and measure it, and write its run folder.

Every run longslam makes goes through `run_frames` (frames in, result and measurements out):
`longslam run` and the demo through `run_sequence` (a sequence folder in, a run folder out), a
study's runs through `study/worker.py` (frames with odometry drawn on the fly).
"""

from __future__ import annotations

import contextlib
import dataclasses
import time
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from longslam.core.errors import InputError, LongslamError, MethodError
from longslam.core.frame import Frame
from longslam.io.atomic import atomic_path, name_final_folder
from longslam.io.partials import clean_stale_partials
from longslam.io.outputs import RUN, check_not_an_input, check_replaceable, replace_guard
from longslam.io.paths import check_output_folder
from longslam.io.sequence import SequenceReader
from longslam.core.memory_release import map_large_blocks
from longslam.run.console import CONSOLE_LOG, native_output_to
from longslam.run.folder import write_result
from longslam.core.progress import bar
from longslam.run.observer import RunObserver
from longslam.run.process_tree import TreeMonitor
from longslam.run.provenance import provenance
from longslam.run.read_ahead import IMAGES, read_ahead
from longslam.run.resources import current_rss_bytes, peak_rss_bytes
from longslam.core.settings import to_mapping
from longslam.slam.api import Closable, MethodContext, Result, images_every_frame
from longslam.slam.catalog import get_spec

RSS_SAMPLE_EVERY = 50  # frames between samples of resident memory


def run_frames(
    method_name: str,
    frames: Iterable[Frame],
    context: MethodContext,
    params: dict[str, Any] | None = None,
    total: int | None = None,
    progress: bool = True,
    observer: RunObserver | None = None,
) -> tuple[Result, dict[str, Any]]:
    """Feed every frame to a new method and finish it. Returns its result and the harness's
    measurements (times, memory, the config the method ran with and the method's own stats).

    `observer` (a live view, say) is shown each frame and the pose returned for it; its time is
    kept out of the method's figures and reported as `observer_time_s`.

    With a `context.output_dir`, what native code prints during the run goes to its
    `console.log` (run/console.py), and the method is told so through `context.console_log`."""
    # A long run's large arrays go back to the system when freed, rather than staying in the heap.
    map_large_blocks()
    baseline_rss = current_rss_bytes()
    spec = get_spec(method_name)
    config = spec.config(params)
    with contextlib.ExitStack() as stack:
        if context.output_dir is not None:
            log = stack.enter_context(native_output_to(Path(context.output_dir) / CONSOLE_LOG))
            context = dataclasses.replace(context, console_log=str(log))
        return _run_method(method_name, spec, config, frames, context, params, total, progress, observer, baseline_rss)


def _run_method(method_name: str, spec: Any, config: Any, frames: Iterable[Frame], context: MethodContext,
                params: dict[str, Any] | None, total: int | None, progress: bool,
                observer: RunObserver | None, baseline_rss: int) -> tuple[Result, dict[str, Any]]:
    method = spec.build(context, config)
    try:
        return _feed(method_name, method, config, spec, frames, context, params, total, progress, observer,
                     baseline_rss)
    except BaseException:  # an error or Ctrl-C before finish returned: nothing of the method outlives the run
        if isinstance(method, Closable):
            method.close()
        raise


# What a method's code may raise and still be reporting, not breaking: longslam's own errors (a
# bad parameter, a program that failed), the system's (a full disk), a lack of memory, an interrupt.
_REPORTED = (LongslamError, OSError, MemoryError, KeyboardInterrupt, SystemExit)


@contextlib.contextmanager
def _method_code(method_name: str, call: str) -> Iterator[None]:
    """Around a call into a method: any other exception is the method's bug, raised as a MethodError
    that names the method and the call, chained to the original so its traceback is kept."""
    try:
        yield
    except _REPORTED:
        raise
    except Exception as err:
        raise MethodError(f"method {method_name!r}: {call} raised {type(err).__name__}: {err}") from err


def _feed(method_name: str, method: Any, config: Any, spec: Any, frames: Iterable[Frame], context: MethodContext,
          params: dict[str, Any] | None, total: int | None, progress: bool, observer: RunObserver | None,
          baseline_rss: int) -> tuple[Result, dict[str, Any]]:
    wanted = set(images_every_frame(method)) | set(getattr(observer, "images_every_frame", ()))
    images = tuple(name for name in IMAGES if name in wanted)
    if images:
        frames = read_ahead(frames, images)
    step_times: list[float] = []
    rss_samples: list[tuple[int, int]] = []
    first_t = last_t = None
    wall_start = time.perf_counter()
    cpu_start = time.process_time()
    monitor = TreeMonitor().start()
    try:
        count = 0
        observer_time = 0.0
        if observer is not None:
            t0 = time.perf_counter()
            observer.start(method, context)
            observer_time += time.perf_counter() - t0
        for frame in bar(frames, total=total, desc=method_name, unit="frame", disable=not progress, leave=False):
            t0 = time.perf_counter()
            with _method_code(method_name, f"step() of frame {frame.index}"):
                pose = method.step(frame)
            step_times.append(time.perf_counter() - t0)
            if np.shape(pose) != (4, 4):
                raise MethodError(f"method {method_name!r} returned a pose of shape {np.shape(pose)} for frame "
                                  f"{frame.index}; expected (4, 4)")
            if first_t is None:
                first_t = frame.timestamp
            last_t = frame.timestamp
            if observer is not None:
                t0 = time.perf_counter()
                observer.frame(frame, pose, method)
                observer_time += time.perf_counter() - t0
            if count % RSS_SAMPLE_EVERY == 0:
                rss_samples.append((count, current_rss_bytes()))
            count += 1
        if count == 0:
            raise InputError("the sequence has no frames")
        t0 = time.perf_counter()
        with _method_code(method_name, "finish()"):
            result = method.finish()
    finally:
        usage = monitor.stop()
    finish_time = time.perf_counter() - t0
    cpu_time = time.process_time() - cpu_start
    if observer is not None:
        t0 = time.perf_counter()
        observer.finish(result)
        observer_time += time.perf_counter() - t0
    wall_time = time.perf_counter() - wall_start
    rss_samples.append((count, current_rss_bytes()))

    steps = np.array(step_times)
    method_time = float(steps.sum() + finish_time)
    assert first_t is not None and last_t is not None  # a sequence without frames stopped above
    duration = float(last_t - first_t) + (float(last_t - first_t) / max(count - 1, 1))
    measurements = {
        **provenance(),
        "method": method_name,
        "params": dict(params or {}),
        "config": to_mapping(config) if spec.config_type is not None else dict(config),
        "frames": count,
        "sequence_duration_s": duration,
        "wall_time_s": wall_time,
        "method_time_s": method_time,
        "finish_time_s": finish_time,
        # CPU time of the whole process, every thread, from the first frame to the end of `finish`:
        # a method with threads of its own (ORB-SLAM3's mapping and loop closing) works beside
        # `step`, which the wall-clock figures above do not see. Reading ahead (and an observer) count too.
        "process_cpu_time_s": cpu_time,
        "step_time_mean_s": float(steps.mean()),
        "step_time_p95_s": float(np.percentile(steps, 95)),
        "step_time_max_s": float(steps.max()),
        # The mean step over each tenth of the frames: whether the per-frame cost grows with the route.
        "step_time_mean_s_by_tenth": [float(part.mean()) for part in np.array_split(steps, 10) if len(part)],
        # Simulated seconds per second of the method's own processing (reading frames excluded).
        "real_time_factor": duration / method_time if method_time > 0 else float("inf"),
        # The CPU the run was denied: how long its threads (and any child processes') were ready to run
        # but waited for a core (run/process_tree.py), and that wait's share of wait plus CPU time.
        "cpu_wait_s": usage.cpu_wait_s,
        "cpu_wait_share": usage.cpu_wait_share,
        "starved": usage.starved,
        "tree_cpu_time_s": usage.cpu_time_s,
        # Whose threads waited: [CPU s, wait s] by thread name, the 8 that waited longest.
        "cpu_wait_by_thread": {name: [round(c, 3), round(w, 3)] for name, (c, w) in list(usage.by_thread.items())[:8]},
        "child_processes": usage.child_processes,
        # The process's own peak, or with child processes (a program run as a method) the largest
        # sum of the tree's resident memory seen in one sample.
        "peak_rss_bytes": max(peak_rss_bytes(), usage.peak_rss_bytes),
        "baseline_rss_bytes": baseline_rss,
        "rss_samples": rss_samples,
        "method_stats": result.stats,
    }
    if observer is not None:
        measurements["observer_time_s"] = observer_time
    return result, measurements


def run_sequence(
    method_name: str,
    sequence: str | Path,
    out: str | Path,
    params: dict[str, Any] | None = None,
    overwrite: bool = False,
    progress: bool = True,
    intrinsics: str | tuple[float, float, float, float] | None = None,
    viz: str | None = None,
) -> dict[str, Any]:
    """Run a method over a sequence on disk and write the run folder `out`. Returns the measurements.

    `intrinsics` (fx, fy, cx, cy) replace the sequence's camera.json or stand in for a missing one.
    `viz`: "viewer" streams the run to a rerun viewer, a path ending in .rrd records it there
    (`longslam.viz.live`, the optional extra `longslam[viz]`)."""
    out = check_output_folder(out, "run folder")
    # --overwrite replaces a run folder, never the sequence or a folder holding it (or the user's files).
    check_not_an_input(out, {"input sequence": sequence}, "run folder")
    check_replaceable(out, RUN, overwrite)
    if viz is not None and viz != "viewer":
        check_not_an_input(viz, {"input sequence": sequence, "run folder": out}, "--viz")
    reader = SequenceReader(sequence, intrinsics=intrinsics)
    if viz is not None:
        from longslam.viz.live import LiveView  # rerun is imported only when a view is asked for

        with LiveView(viz, f"{method_name} on {Path(sequence).name}", truth=reader.ground_truth,
                      overwrite=overwrite) as view:
            return _run_into(method_name, sequence, reader, out, params, overwrite, progress, view)
    return _run_into(method_name, sequence, reader, out, params, overwrite, progress, None)


def _run_into(method_name: str, sequence: str | Path, reader: SequenceReader, out: Path, params: dict[str, Any] | None,
              overwrite: bool, progress: bool, observer: RunObserver | None) -> dict[str, Any]:
    clean_stale_partials(out.parent)  # run folders of runs that were killed
    # Without --overwrite the final rename refuses a folder another run finished meanwhile.
    with atomic_path(out, overwrite=overwrite, may_replace=replace_guard(RUN)) as tmp:
        tmp.mkdir(parents=True)
        context = MethodContext(reader.intrinsics, reader.max_depth, str(tmp))
        result, measurements = run_frames(method_name, reader, context, params, total=len(reader), progress=progress,
                                          observer=observer)
        measurements["sequence"] = str(Path(sequence).resolve())
        measurements["intrinsics"] = {**reader.intrinsics.to_dict(), "source": reader.intrinsics_source}
        if reader.notes:
            measurements["sequence_notes"] = list(reader.notes)
        measurements = name_final_folder(measurements, tmp, out)
        write_result(tmp, result, measurements)
    return measurements
