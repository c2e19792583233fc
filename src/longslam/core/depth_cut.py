"""A depth image cut at a range: the one rule that both a sensor's short reach (the simulator's
`depth-range` perturbation) and a method's trusted range (`slam/depth_trust`) apply."""

from __future__ import annotations

import numpy as np


def depth_within(depth: np.ndarray, limit: float) -> np.ndarray:
    """`depth` (float32 metres, 0 = no return) with every return beyond `limit` set to no return."""
    return np.where(depth <= limit, depth, np.float32(0)).astype(np.float32, copy=False)
