"""The one scorer: a trajectory against the ground truth. `longslam evaluate`, the demo, studies
and the benchmarks all score through here, so a figure means the same wherever it is printed.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from longslam.errors import InputError
from longslam.eval.metrics import MIN_STEP, evaluate
from longslam.eval.sync import associate, associate_by_index
from longslam.io.trajectory_files import KITTI, read_trajectory
from longslam.run.folder import TRAJECTORY
from longslam.trajectory import Trajectory

MAX_DIFF = 0.01  # seconds between matched stamps (the CLI's --max-diff default)


def score(
    truth: Trajectory, estimate: Trajectory, align: str = "none", max_diff: float = MAX_DIFF,
    by_index: bool = False, what: str = "the estimate", min_step: float = MIN_STEP,
) -> dict[str, Any]:
    """The paper's metrics and the field's (see `eval.metrics.evaluate`) of `estimate` against
    `truth`, poses matched by timestamp (or by index). A metric that overflowed is an error: it
    measures nothing, and JSON could not hold it."""
    ref, est = associate_by_index(truth, estimate) if by_index else associate(truth, estimate, max_diff=max_diff)
    with np.errstate(all="ignore"):  # overflow is reported below, as one error
        scores = evaluate(ref, est, align=align, min_step=min_step)
    bad = [key for key, value in scores.items() if isinstance(value, float) and not math.isfinite(value)]
    if bad:
        raise InputError(
            f"{what}: {', '.join(bad)} overflowed to NaN or infinity; "
            "the poses hold coordinates too large to score (expected metres)"
        )
    return scores


def trajectory_file(path: str | Path, names: tuple[str, ...]) -> Path:
    """A trajectory file, or the usual file inside a run or sequence folder."""
    path = Path(path)
    if path.is_dir():
        for name in names:
            if (path / name).is_file():
                return path / name
        raise InputError(f"{path} is a folder without {' or '.join(names)}")
    return path


def score_files(estimate: str | Path, truth: str | Path, align: str = "none", max_diff: float = MAX_DIFF,
                min_step: float = MIN_STEP) -> dict[str, Any]:
    """Score trajectory files (TUM or KITTI) or run / sequence folders. KITTI files have no stamps,
    so they are matched by index."""
    est, est_format = read_trajectory(trajectory_file(estimate, (TRAJECTORY,)))
    ref, ref_format = read_trajectory(trajectory_file(truth, ("groundtruth.txt",)))
    return score(ref, est, align, max_diff, by_index=KITTI in (est_format, ref_format), what=f"{estimate} against {truth}",
                 min_step=min_step)
