"""A run's native libraries kept to the cores its method declares (`MethodSpec.threads`).

OpenCV splits a call (Lucas-Kanade tracking, corner detection) over a pool of one thread per
core. A one-core method's run already keeps another core busy reading ahead, and a study at
`--jobs 2` gives that core to another run, so the pool's second thread waits for a CPU while the
method's thread waits for it (`cpu_wait_by_thread` in a run's stats shows that wait). The calls
work point by point or pixel by pixel, so one thread gives the results the pool gives.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import cv2


@contextlib.contextmanager
def native_threads(threads: int) -> Iterator[None]:
    """OpenCV's pool at `threads` threads for the duration, then as it was."""
    before = cv2.getNumThreads()
    cv2.setNumThreads(max(1, int(threads)))
    try:
        yield
    finally:
        cv2.setNumThreads(before)
