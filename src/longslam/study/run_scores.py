"""What a study keeps of a finished run's quality: its metrics (through the one scorer,
`run.score.score`), the online trajectory's ATE, curves of error and memory against distance
travelled, and the map's quality.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from longslam.core.gridmap import GridMap
from longslam.core.trajectory import Trajectory
from longslam.eval.align import alignment
from longslam.eval.map_quality import map_scores
from longslam.eval.metrics import ape_errors, ate
from longslam.eval.sync import associate
from longslam.run.measurements import RunMeasurements
from longslam.run.score import score
from longslam.slam.api import Result

CURVE_POINTS = 600  # at most this many points of each curve (error, memory) are kept per run
TruthLoader = Callable[[], tuple[GridMap, np.ndarray]]


def _thin(points: list[tuple[float, float]]) -> list[list[float]]:
    if len(points) <= CURVE_POINTS:
        return [list(map(float, p)) for p in points]
    idx = np.unique(np.linspace(0, len(points) - 1, CURVE_POINTS).round().astype(int))
    return [list(map(float, points[i])) for i in idx]


def _thin_places(xy: np.ndarray, most: int = 500) -> list[list[float]]:
    """At most `most` of the (K, 2) doubled-wall places, to the centimetre: enough to mark them on
    a map figure, small in the database."""
    if len(xy) > most:
        xy = xy[np.unique(np.linspace(0, len(xy) - 1, most).round().astype(int))]
    return [[round(float(x), 2), round(float(y), 2)] for x, y in xy]


def score_run(
    result: Result,
    measurements: RunMeasurements,
    truth: Trajectory,
    align: str = "none",
    load_truth: TruthLoader | None = None,
    map_tolerance_cells: float = 2.0,
) -> dict[str, Any]:
    """Metrics, the online trajectory's ATE, curves of error and memory against distance travelled,
    and the map's quality (when the method built a grid and `load_truth` gives the world's): as it
    is, after its best planar alignment, and its share of doubled walls (`eval.map_quality.map_scores`)."""
    metrics = score(truth, result.trajectory, align)
    ref, est = associate(truth, result.trajectory)
    ref_online, est_online = associate(truth, result.online)
    metrics["ate_online"] = ate(ref_online, est_online)

    travelled = truth.distances()
    at = np.clip(np.searchsorted(truth.timestamps, ref.timestamps), 0, len(truth) - 1)
    errors = ape_errors(ref, est, "translation")  # the ATE's per-pose term: no alignment
    error_curve = _thin(list(zip(travelled[at], errors)))
    memory_curve = _thin([(travelled[min(int(i), len(truth) - 1)], rss) for i, rss in measurements.rss_samples])

    quality = None
    if result.grid is not None and load_truth is not None:
        grid, observed = load_truth()
        rotation, translation, scale = alignment(est, ref, align)
        quality = map_scores(
            result.grid,
            grid,
            map_tolerance_cells,
            observed,
            rotation,
            translation,
            scale,
            height=float(np.mean(est.positions[:, 2])),
            with_places=True,
        )
        quality["map_doubled_places"] = _thin_places(quality["map_doubled_places"])
    return {"metrics": metrics, "map_quality": quality, "error_curve": error_curve, "memory_curve": memory_curve}
