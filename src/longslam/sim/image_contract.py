"""What a plugin's images must be (a sensor model's `sense()`, a perturbation's `perturb()`), and the
one-line error naming the plugin, the frame and what it returned when they are not."""

from __future__ import annotations

from typing import Any

import numpy as np

from longslam.core.errors import InputError


def checked_images(
    where: str, call: str, rgb: Any, depth: Any, shape: tuple[int, int]
) -> tuple[np.ndarray, np.ndarray]:
    """(rgb, depth) as arrays if they are uint8 (H, W, 3) and finite float32 (H, W) metres >= 0;
    otherwise InputError "`where`: `call` returned ...; expected ..."."""
    try:
        rgb, depth = np.asarray(rgb), np.asarray(depth)
    except Exception:  # a ragged list, say
        rgb, depth = np.asarray(None), np.asarray(None)
    if rgb.dtype != np.uint8 or rgb.shape != shape + (3,):
        raise InputError(f"{where}: {call} returned rgb {rgb.dtype} {rgb.shape}; expected uint8 {shape + (3,)}")
    if depth.dtype != np.float32 or depth.shape != shape:
        raise InputError(f"{where}: {call} returned depth {depth.dtype} {depth.shape}; expected float32 {shape}")
    if not np.all(np.isfinite(depth)) or (depth.size and depth.min() < 0):
        raise InputError(
            f"{where}: {call} returned depth with NaN, inf or negative values; " "expected metres >= 0, 0 for no return"
        )
    return rgb, depth
