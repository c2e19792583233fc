"""The run engine: feed frames to a method, time and measure it, and write its run folder.

Every run longslam makes goes through `run_frames` (frames in, result and measurements out):
`longslam run` and the demo through `run_sequence` (a sequence folder in, a run folder out), a
study's runs through `study/worker.py` (frames with odometry drawn on the fly).
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from longslam.core import progress as bars
from longslam.core.errors import InputError, LongslamError, MethodError
from longslam.core.frame import Frame
from longslam.core.memory_release import map_large_blocks
from longslam.core.progress import bar
from longslam.core.settings import to_mapping
from longslam.io.atomic import atomic_path
from longslam.io.overwrite_policy import RUN, check_not_an_input, check_replaceable, replace_guard
from longslam.io.partials import clean_stale_partials
from longslam.io.paths import check_output_folder
from longslam.io.sequence import SequenceReader
from longslam.io.sequence.layout import ODOMETRY
from longslam.run.console import CONSOLE_LOG, native_output_to
from longslam.run.cores import native_threads
from longslam.run.depth_delay import check_depth_delay, run_frames_in_step
from longslam.run.folder import write_result
from longslam.run.isolate import prepare_method, run_isolated
from longslam.run.measurements import RunMeasurements
from longslam.run.meter import RunMeter
from longslam.run.observer import RunObserver
from longslam.run.process_tree import TreeUsage
from longslam.run.provenance import provenance
from longslam.run.read_ahead import IMAGES, read_ahead
from longslam.run.resources import current_rss_bytes
from longslam.slam.api import Closable, MethodChoice, MethodContext, Result, ahead_work, wanted_images


def run_frames(
    method: MethodChoice,
    frames: Iterable[Frame],
    context: MethodContext,
    total: int | None = None,
    progress: bool = True,
    observer: RunObserver | None = None,
) -> tuple[Result, RunMeasurements]:
    """Feed every frame to a new method (`method`'s, built with its checked config) and finish it.
    Returns its result and the harness's
    measurements (times, memory, the config the method ran with and the method's own stats).

    `observer` (a live view, say) is shown each frame and the pose returned for it; its time is
    kept out of the method's figures and reported as `observer_time_s`.

    With a `context.output_dir`, what native code prints during the run goes to its
    `console.log` (run/console.py), and the method is told so through `context.console_log`."""
    # A long run's large arrays go back to the system when freed, rather than staying in the heap.
    map_large_blocks()
    baseline_rss = current_rss_bytes()
    with contextlib.ExitStack() as stack:
        stack.enter_context(native_threads(method.spec.threads))
        if context.output_dir is not None:
            log = stack.enter_context(native_output_to(Path(context.output_dir) / CONSOLE_LOG))
            context = dataclasses.replace(context, console_log=str(log))
        built = method.spec.build(context, method.config)
        try:
            return _feed(method, built, frames, context, total, progress, observer, baseline_rss)
        except BaseException:  # an error or Ctrl-C before finish returned: nothing of the method outlives the run
            if isinstance(built, Closable):
                built.close()
            raise


# What a method's code may raise and still be reporting, not breaking: longslam's own errors (a
# bad parameter, a program that failed), the system's (a full disk), a lack of memory, an interrupt.
_REPORTED = (LongslamError, OSError, MemoryError, KeyboardInterrupt, SystemExit)


@contextlib.contextmanager
def _method_code(method_name: str, call: str, frame: int | None = None) -> Iterator[None]:
    """Around a call into a method: any other exception is the method's bug, raised as a MethodError
    that names the method and the call (of `frame`), chained to the original so its traceback is
    kept. The message is made only on failure: this wraps every step."""
    try:
        yield
    except _REPORTED:
        raise
    except Exception as err:
        where = call if frame is None else f"{call} of frame {frame}"
        raise MethodError(f"method {method_name!r}: {where} raised {type(err).__name__}: {err}") from err


def _guarded_work(method_name: str, work: Callable[[Frame], None] | None) -> Callable[[Frame], None] | None:
    """The method's `work_ahead`, its errors raised as the method's (`_method_code`)."""
    if work is None:
        return None

    def guarded(frame: Frame) -> None:
        with _method_code(method_name, "work_ahead()", frame.index):
            work(frame)

    return guarded


def _feed(
    choice: MethodChoice,
    method: Any,
    frames: Iterable[Frame],
    context: MethodContext,
    total: int | None,
    progress: bool,
    observer: RunObserver | None,
    baseline_rss: int,
) -> tuple[Result, RunMeasurements]:
    method_name = choice.name
    wanted = set(wanted_images(method)) | set(getattr(observer, "images_every_frame", ()))
    images = tuple(name for name in IMAGES if name in wanted)
    # A real-time system is fed at the sequence's own rate: reading ahead saves it nothing, and its
    # thread would compete with the system's own for the cores.
    if images and not choice.spec.real_time:
        frames = read_ahead(frames, images, work=_guarded_work(method_name, ahead_work(method)))
    meter = RunMeter()
    try:
        if observer is not None:
            with meter.observer():
                observer.start(method, context)
        for frame in bar(frames, total=total, desc=method_name, unit="frame", disable=not progress, leave=False):
            with meter.step(), _method_code(method_name, "step()", frame.index):
                pose = method.step(frame)
            if np.shape(pose) != (4, 4):
                raise MethodError(
                    f"method {method_name!r} returned a pose of shape {np.shape(pose)} for frame "
                    f"{frame.index}; expected (4, 4)"
                )
            meter.frame_done(frame.timestamp)
            if observer is not None:
                with meter.observer():
                    observer.frame(frame, pose, method)
        if meter.frames == 0:
            raise InputError("the sequence has no frames")
        with meter.finish(), _method_code(method_name, "finish()"):
            result = method.finish()
    finally:
        usage = meter.stop()
    if observer is not None:
        with meter.observer():
            observer.finish(result)
    return result, _measurements(choice, meter, usage, baseline_rss, result, observer is not None)


def _measurements(
    choice: MethodChoice, meter: RunMeter, usage: TreeUsage, baseline_rss: int, result: Result, observed: bool
) -> RunMeasurements:
    wall_time = meter.wall_time()
    steps = meter.steps()
    method_time = float(steps.sum() + meter.finish_time)
    duration = meter.sequence_duration()
    source = provenance()
    return RunMeasurements(
        longslam_version=str(source["longslam_version"]),
        longslam_commit=source["longslam_commit"],
        method=choice.name,
        params=dict(choice.params),
        config=to_mapping(choice.config) if choice.spec.config_type is not None else dict(choice.config),
        frames=meter.frames,
        sequence_duration_s=duration,
        wall_time_s=wall_time,
        method_time_s=method_time,
        finish_time_s=meter.finish_time,
        process_cpu_time_s=meter.cpu_time,
        step_time_mean_s=float(steps.mean()),
        step_time_p95_s=float(np.percentile(steps, 95)),
        step_time_max_s=float(steps.max()),
        step_time_mean_s_by_tenth=[float(part.mean()) for part in np.array_split(steps, 10) if len(part)],
        # A sequence that spans no time (one frame) has no pace to compare: None, not 0 ("slower than
        # real time" of a run that took a millisecond).
        real_time_factor=None if duration <= 0 else duration / method_time if method_time > 0 else float("inf"),
        cpu_wait_s=usage.cpu_wait_s,
        cpu_wait_share=usage.cpu_wait_share,
        starved=usage.starved,
        tree_cpu_time_s=usage.cpu_time_s,
        cpu_wait_by_thread={name: [round(c, 3), round(w, 3)] for name, (c, w) in list(usage.by_thread.items())[:8]},
        child_processes=usage.child_processes,
        peak_rss_bytes=meter.peak_rss(),
        baseline_rss_bytes=baseline_rss,
        rss_samples=meter.rss_samples,
        method_stats=result.stats,
        observer_time_s=meter.observer_time if observed else None,
    )


def run_into_folder(
    out: Path,
    method: MethodChoice,
    frames: Iterable[Frame],
    reader: SequenceReader,
    about: dict[str, Any],
    *,
    progress: bool = False,
    observer: RunObserver | None = None,
    overwrite: bool = False,
    may_replace: Callable[[Path], None] | None = None,
    before_rename: Callable[[Path, Result, RunMeasurements], None] | None = None,
) -> tuple[Result, RunMeasurements]:
    """Run `method` over `frames` (of the sequence `reader` reads) into the run folder `out`,
    whole or not at all: the method works in a temporary folder, its files and stats.json (with
    `about`: what the run was given) are written there, `before_rename(tmp, ...)` adds its own, and
    the folder is renamed to `out` last. Returns the result and the measurements."""
    with atomic_path(out, overwrite=overwrite, may_replace=may_replace) as tmp:
        tmp.mkdir(parents=True)
        context = MethodContext(reader.intrinsics, reader.max_depth, str(tmp))
        result, measurements = run_frames(
            method, frames, context, total=len(reader), progress=progress, observer=observer
        )
        measurements.about.update(about)
        measurements = measurements.in_folder(tmp, out)
        write_result(tmp, result, measurements)
        if before_rename is not None:
            before_rename(tmp, result, measurements)
    return result, measurements


def run_sequence(
    method: MethodChoice,
    sequence: str | Path,
    out: str | Path,
    overwrite: bool = False,
    progress: bool = True,
    intrinsics: str | tuple[float, float, float, float] | None = None,
    viz: str | None = None,
    prepare: bool = False,
    depth_delay: float | None = None,
) -> RunMeasurements:
    """Run `method` over a sequence on disk and write the run folder `out`. Returns the measurements.

    `intrinsics` (fx, fy, cx, cy) replace the sequence's camera.json or stand in for a missing one.
    `prepare`: first do the method's once-per-machine work (ORB-SLAM3's default vocabulary, say) in
    a process of its own, once the inputs are checked, so that it is in neither the run's time nor
    its peak memory (this process's peak is part of the run's); a study or the demo prepares once
    for all its runs instead.
    `viz`: "viewer" streams the run to a rerun viewer, a path ending in .rrd records it there
    (`longslam.viz.live`, the optional extra `longslam[viz]`).
    `depth_delay`: the seconds the sequence's depth lags its colour (negative: leads); each depth
    image is moved back in step by the odometry before the method sees it (`run/depth_delay.py`)."""
    out = check_output_folder(out, "run folder")
    # --overwrite replaces a run folder, never the sequence or a folder holding it (or the user's files).
    check_not_an_input(out, {"input sequence": sequence}, "run folder")
    check_replaceable(out, RUN, overwrite)
    if viz is not None and viz != "viewer":
        check_not_an_input(viz, {"input sequence": sequence, "run folder": out}, "--viz")
    reader = SequenceReader(sequence, intrinsics=intrinsics)
    if depth_delay is not None:
        depth_delay = check_depth_delay(depth_delay)
        if reader.odometry is None:
            raise InputError(f"{reader.path}: no {ODOMETRY}, which --depth-delay needs to move each depth image")
    if prepare and method.spec.prepare is not None:
        run_isolated(
            prepare_method,
            method.spec,
            method.config,
            bars.setting() if progress else False,
            logging.getLogger("longslam").getEffectiveLevel(),
        )
    if viz is not None:
        from longslam.viz.live import LiveView  # rerun is imported only when a view is asked for

        with LiveView(
            viz, f"{method.name} on {Path(sequence).name}", truth=reader.ground_truth, overwrite=overwrite
        ) as view:
            return _run_into(method, sequence, reader, out, overwrite, progress, view, depth_delay)
    return _run_into(method, sequence, reader, out, overwrite, progress, None, depth_delay)


def _run_into(
    method: MethodChoice,
    sequence: str | Path,
    reader: SequenceReader,
    out: Path,
    overwrite: bool,
    progress: bool,
    observer: RunObserver | None,
    depth_delay: float | None = None,
) -> RunMeasurements:
    clean_stale_partials(out.parent)  # run folders of runs that were killed
    about: dict[str, Any] = {
        "sequence": str(Path(sequence).resolve()),
        "intrinsics": {**reader.intrinsics.to_dict(), "source": reader.intrinsics_source},
    }
    if reader.notes:
        about["sequence_notes"] = list(reader.notes)
    frames: Iterable[Frame] = reader
    if depth_delay is not None:
        frames = run_frames_in_step(reader, depth_delay, str(reader.path), about)
    # Without --overwrite the final rename refuses a folder another run finished meanwhile.
    _, measurements = run_into_folder(
        out,
        method,
        frames,
        reader,
        about,
        progress=progress,
        observer=observer,
        overwrite=overwrite,
        may_replace=replace_guard(RUN),
    )
    return measurements
