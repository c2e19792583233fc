"""Stretches of a route: where a burst of dropped frames, a dimmed stretch or a depth dropout
falls.

The route is cut into windows of about `PERIOD_S` each (a whole number of equal windows, at least
one, so a short route still gets one stretch); each window holds one stretch of the asked length
at a moment drawn uniformly within it, from a generator keyed by (perturbation name, seed,
window) alone. A frame finds its stretch from its own window's draw, so frames are perturbed one
at a time, in any order, and the same way in `simulate` and in a study.
"""

from __future__ import annotations

import math
import zlib

import numpy as np

PERIOD_S = 60.0  # about one stretch per minute of the route


def window_count(start: float, end: float) -> int:
    """How many windows a route from `start` to `end` (seconds) is cut into."""
    return max(1, round((end - start) / PERIOD_S))


def stretch_start(name: str, seed: int, window: int, start: float, end: float, length: float) -> float:
    """When the stretch of `window` begins: uniform over the window, so it ends inside it when it fits."""
    count = window_count(start, end)
    size = (end - start) / count
    begin = start + window * size
    room = max(size - length, 0.0)
    rng = np.random.default_rng([zlib.crc32(f"perturbation/{name}/stretch".encode("utf-8")), int(seed), int(window)])
    return begin + float(rng.uniform(0.0, 1.0)) * room


def in_stretch(name: str, seed: int, t: float, start: float, end: float, length: float) -> bool:
    """Whether time `t` falls in a stretch of `length` seconds of the perturbation `name`."""
    count = window_count(start, end)
    size = (end - start) / count if end > start else 1.0
    window = min(max(int(math.floor((t - start) / size)), 0), count - 1)
    begin = stretch_start(name, seed, window, start, end, length)
    return begin <= t < begin + length
