"""The clocks and samplers around one run: each step's time, finish's, an observer's (kept apart),
resident memory every few frames and the process tree's CPU and wait (run/process_tree.py)."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator

import numpy as np

from longslam.run.process_tree import TreeMonitor, TreeUsage
from longslam.run.resources import current_rss_bytes, peak_rss_bytes

RSS_SAMPLE_EVERY = 50  # frames between samples of resident memory


class RunMeter:
    """Started before the first frame; `step`, `finish` and `observer` time their blocks; `frame_done`
    samples memory; `stop` ends the process-tree sampling once the method has finished."""

    def __init__(self) -> None:
        self.step_times: list[float] = []
        self.rss_samples: list[tuple[int, int]] = []
        self.finish_time = 0.0
        self.observer_time = 0.0
        self.frames = 0
        self.first_stamp: float | None = None
        self.last_stamp: float | None = None
        self._wall_start = time.perf_counter()
        self._cpu_start = time.process_time()
        self._monitor = TreeMonitor().start()
        self.usage: TreeUsage | None = None
        self.cpu_time = 0.0

    @contextlib.contextmanager
    def step(self) -> Iterator[None]:
        start = time.perf_counter()
        yield
        self.step_times.append(time.perf_counter() - start)

    @contextlib.contextmanager
    def finish(self) -> Iterator[None]:
        start = time.perf_counter()
        yield
        self.finish_time = time.perf_counter() - start

    @contextlib.contextmanager
    def observer(self) -> Iterator[None]:
        start = time.perf_counter()
        yield
        self.observer_time += time.perf_counter() - start

    def frame_done(self, timestamp: float) -> None:
        if self.first_stamp is None:
            self.first_stamp = timestamp
        self.last_stamp = timestamp
        if self.frames % RSS_SAMPLE_EVERY == 0:
            self.rss_samples.append((self.frames, current_rss_bytes()))
        self.frames += 1

    def stop(self) -> TreeUsage:
        """End the tree's sampling and the CPU clock (at the end of `finish`, or of a failed run)."""
        if self.usage is None:
            self.usage = self._monitor.stop()
            self.cpu_time = time.process_time() - self._cpu_start
        return self.usage

    def wall_time(self) -> float:
        """Seconds since the meter started; the final sample of memory is taken with it."""
        self.rss_samples.append((self.frames, current_rss_bytes()))
        return time.perf_counter() - self._wall_start

    def sequence_duration(self) -> float:
        """The frames' span, plus one mean frame interval (the last frame lasts too)."""
        assert self.first_stamp is not None and self.last_stamp is not None
        span = float(self.last_stamp - self.first_stamp)
        return span + span / max(self.frames - 1, 1)

    def steps(self) -> np.ndarray:
        return np.array(self.step_times)

    def peak_rss(self) -> int:
        usage = self.stop()
        return max(peak_rss_bytes(), usage.peak_rss_bytes)
