"""Decode the next frames' images on a second thread while the method works on this one.

A method that looks at every frame (the fused front end, a TSDF) would otherwise wait for two
PNG decodes (colour and depth) a frame. OpenCV releases the GIL
while it decodes, so the reading overlaps the method's own work on a two-core machine. Methods
that look at one frame in ten (keyframe on wheel odometry) keep the lazy reads instead: decoding
every frame ahead would cost them ten times the reading they need, and so do real-time systems
(the engine's choice): they take frames at the sequence's own rate, so reading ahead saves them
nothing, while its thread competes with theirs for the cores.

A method may also give work to do on each frame ahead (its `work_ahead`, see `slam/api.py`): what
it computes from a frame's images alone. The same thread does it, after the frame's images are
decoded and before the method's step takes the frame; a third busy thread would make the run's
threads wait for the two cores. The thread is then named for the method's work as well as the
reading ("longslam-ahead"), since its CPU wait is partly the method's.
"""

from __future__ import annotations

import ctypes
import sys
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor

from longslam.core.frame import Frame

DEFAULT_AHEAD = 4  # frames decoded ahead: enough to hide a slow decode, little memory (4 x 0.5 MB)


IMAGES = ("rgb", "depth")
THREAD_NAME = "longslam-read"  # the reading thread's name in /proc (`comm`): its CPU wait is the harness's
WORK_THREAD_NAME = "longslam-ahead"  # the same thread when it also does a method's work ahead


def _os_thread_named(name: str) -> Callable[[], None]:
    """A thread initializer that gives the thread `name` in /proc, so a run's CPU wait by thread
    tells the harness's reading from the method's own threads (Python names its threads for
    itself only)."""

    def name_os_thread() -> None:
        if not sys.platform.startswith("linux"):
            return
        try:
            ctypes.CDLL(None).prctl(15, name.encode(), 0, 0, 0)  # PR_SET_NAME
        except (OSError, AttributeError):
            pass

    return name_os_thread


def _load(frame: Frame, images: tuple[str, ...], work: Callable[[Frame], None] | None) -> None:
    # Reading an attribute runs the frame's loader once and keeps the array on the frame.
    for name in images:
        getattr(frame, name)
    if work is not None:
        work(frame)


def read_ahead(
    frames: Iterable[Frame],
    images: tuple[str, ...] = IMAGES,
    ahead: int = DEFAULT_AHEAD,
    work: Callable[[Frame], None] | None = None,
) -> Iterator[Frame]:
    """The same frames in the same order, each with the named images ("rgb", "depth") loaded and,
    given `work`, `work(frame)` done after them, frame after frame in order.

    A read error (a missing or corrupt image) is raised here, for the frame it belongs to, as
    the lazy read would have raised it; so is an error of `work`."""
    if ahead < 1:
        raise ValueError(f"ahead must be at least 1, got {ahead}")
    unknown = set(images) - set(IMAGES)
    if unknown:
        raise ValueError(f"images to read ahead must be among {IMAGES}, got {sorted(unknown)}")
    pending: deque[tuple[Frame, Future]] = deque()
    name = THREAD_NAME if work is None else WORK_THREAD_NAME
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix=name, initializer=_os_thread_named(name)) as pool:
        try:
            for frame in frames:
                pending.append((frame, pool.submit(_load, frame, tuple(images), work)))
                if len(pending) > ahead:
                    done, future = pending.popleft()
                    future.result()
                    yield done
            while pending:
                done, future = pending.popleft()
                future.result()
                yield done
        finally:
            # A consumer that stops early (an error in the method) must not wait for reads or
            # work it will never use.
            for _, future in pending:
                future.cancel()
