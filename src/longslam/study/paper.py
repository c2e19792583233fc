"""The paper's own numbers (its Tables 1 and 2), shipped as reference data beside the reports.

A. Muravyev and K. Yakovlev, "Evaluation of RGB-D SLAM in Large Indoor Environments", ICR 2022.
The CSV files are in `longslam/study/reference/` (see the README there).
"""

from __future__ import annotations

import csv
import functools
import io
from dataclasses import dataclass
from importlib import resources

CITATION = 'A. Muravyev and K. Yakovlev, "Evaluation of RGB-D SLAM in Large Indoor Environments", ' "ICR 2022"
# The paper's systems, as they are named in its tables.
PAPER_METHODS = {"rtabmap": "RTAB-Map", "voxgraph": "Voxgraph"}
# longslam route -> the paper's route of the same design.
PAPER_ROUTES = {"paper-300m": "300m", "paper-1km": "1km"}
PAPER_NOISE = ("small", "medium", "large", "xlarge")
ACCURACY_METRICS = ("e_trans", "e_rot", "ate")


@dataclass(frozen=True)
class PaperValue:
    mean: float
    std: float | None  # Table 2 gives no std
    text: str  # as printed in the paper: "5.00 ± 0.23", "8.6"


def _rows(name: str) -> list[dict[str, str]]:
    text = resources.files("longslam.study").joinpath("reference", name).read_text(encoding="utf-8")
    lines = [line for line in text.splitlines() if line.strip() and not line.startswith("#")]
    return list(csv.DictReader(io.StringIO("\n".join(lines))))


@functools.lru_cache(maxsize=None)
def paper_accuracy() -> dict[tuple[str, str, str, str], PaperValue]:
    """(method, paper route, noise, metric) -> mean and std of Table 1."""
    return {
        (r["method"], r["route"], r["noise"], r["metric"]): PaperValue(
            float(r["mean"]), float(r["std"]), f"{r['mean']} ± {r['std']}"
        )
        for r in _rows("paper_accuracy.csv")
    }


@functools.lru_cache(maxsize=None)
def paper_memory_gb() -> dict[tuple[str, str, str], PaperValue]:
    """(method, paper route, noise) -> memory in GB of Table 2."""
    return {
        (r["method"], r["route"], r["noise"]): PaperValue(float(r["memory_gb"]), None, r["memory_gb"])
        for r in _rows("paper_memory.csv")
    }


def paper_route(route: str) -> str | None:
    """The paper's route matching a longslam route name, or None."""
    return PAPER_ROUTES.get(route)
