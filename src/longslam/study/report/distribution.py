"""A non-deterministic system's results as a distribution: per cell, the ATE's median, quartiles
and range over its runs, and how often a run failed, by a rule the report prints.

The paper's mean +- std stays in Table 1; a system whose threads race can give 0.06 m and 11 m on
the same sequence, and a mean of such runs describes neither.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from longslam.run.process_tree import STARVED_SHARE, starved
from longslam.study.report.results import StudyResults, on_camera
from longslam.study.report.tables import Cell, Table, format_number

# The longest stretch of untracked frames a run may have and still count as a success.
LONGEST_LOSS_S = 2.0
FAILURE_RULE = (
    f"A run counts as failed if it ended in an error, started a second map (a tracking loss it did not "
    f"recover from in the first map), lost tracking for more than {LONGEST_LOSS_S:g} s in a row, or ended "
    "with an ATE above dead reckoning's (`odometry`) on the same sequence, where the study ran it."
)


def _stats(run: dict[str, Any]) -> dict[str, Any]:
    return (run.get("measurements") or {}).get("method_stats") or {}


def failure_reason(run: dict[str, Any], dead_reckoning_ate: float | None) -> str | None:
    """Why `run` counts as failed under FAILURE_RULE, or None."""
    if run["status"] != "ok":
        return "error"
    stats = _stats(run)
    if int(stats.get("maps_started", stats.get("maps", 1)) or 1) > 1:
        return "new map"
    if float(stats.get("tracking_lost_longest_s", 0.0) or 0.0) > LONGEST_LOSS_S:
        return "tracking lost"
    if dead_reckoning_ate is not None and run.get("ate") is not None and run["ate"] > dead_reckoning_ate:
        return "worse than dead reckoning"
    return None


def _sequence(run: dict[str, Any]) -> tuple:
    return run["route"], run.get("camera_name"), run.get("sensor"), run.get("perturbation"), run["noise"], run["seed"]


def dead_reckoning_ates(runs: list[dict[str, Any]]) -> dict[tuple, float]:
    """Dead reckoning's ATE on each sequence of `runs` (its first repeat's), by sequence."""
    return {
        _sequence(r): r["ate"]
        for r in runs
        if r["status"] == "ok"
        and r.get("method_name") == "odometry"
        and r.get("ate") is not None
        and not r.get("repeat")
    }


def failure_reasons(runs: list[dict[str, Any]], dead: dict[tuple, float]) -> list[str]:
    """Why each failed run of `runs` failed under FAILURE_RULE, against dead reckoning's ATE on its
    sequence (`dead_reckoning_ates`); the runs that did not fail give nothing."""
    return [reason for reason in (failure_reason(r, dead.get(_sequence(r))) for r in runs) if reason]


def failures_text(runs: list[dict[str, Any]], dead: dict[tuple, float]) -> str:
    """'k / n (reasons)': how many of a cell's runs failed under FAILURE_RULE, and why."""
    failed = failure_reasons(runs, dead)
    why = f" ({', '.join(sorted(set(failed)))})" if failed else ""
    return f"{len(failed)} / {len(runs)}{why}"


def _nondeterministic(results: StudyResults) -> set[str]:
    """The study's method labels whose method declares itself non-deterministic."""
    from longslam.core.errors import LongslamError
    from longslam.slam.catalog import get_spec

    labels = set()
    for run in results.runs:
        try:
            if not get_spec(run["method_name"]).deterministic:
                labels.add(run["method"])
        except LongslamError:  # a plugin no longer installed: judged by its runs alone
            pass
    return labels


def distribution_table(results: StudyResults) -> Table | None:
    """Per cell of a non-deterministic method (or of every method, in a study with repeats):
    ATE median, quartiles, range, failures and starved runs. None if no cell has such runs."""
    repeats = int(results.config.get("repeats", 1) or 1)
    labels = _nondeterministic(results) if repeats == 1 else set(results.methods)
    if not labels:
        return None
    dead = dead_reckoning_ates(results.runs)
    headings = (
        "runs",
        "ATE median [m]",
        "ATE quartiles [m]",
        "ATE min-max [m]",
        "ATE mean +- std [m]",
        "failed",
        "starved",
    )
    columns = [(f"{route} {noise}", heading) for route, noise in results.columns for heading in headings]
    table = Table(
        "Distributions",
        "Per cell of each non-deterministic method (or of every method, in a study with repeats), over its runs "
        "(seeds and repeats): the ATE's median, quartiles (25th-75th percentile) and range beside the mean +- std; "
        "the share of runs that failed (the rule is below the tables) and the runs starved of CPU (a CPU wait "
        f"share over {STARVED_SHARE:g}).",
        columns,
        [],
        group_title=results.group_title or "camera",
    )
    for method in (m for m in results.methods if m in labels):
        for group in results.row_cameras:
            mine = [r for r in results.runs if r["method"] == method and on_camera(r, group)]
            if not mine:
                continue
            cells: list[Cell] = []
            for route, noise in results.columns:
                cell = [r for r in mine if (r["route"], r["noise"]) == (route, noise)]
                cells += _cells(cell, dead)
            table.add_row((method, ""), cells, group)
    return table if table.rows else None


def _cells(runs: list[dict[str, Any]], dead: dict[tuple, float]) -> list[Cell]:
    if not runs:
        return [Cell("–") for _ in range(7)]
    ates = np.array([r["ate"] for r in runs if r["status"] == "ok" and r.get("ate") is not None], dtype=float)
    starved_runs = sum(1 for r in runs if starved(r.get("cpu_wait_share")))
    if len(ates):
        q1, median, q3 = np.percentile(ates, [25, 50, 75])
        spread = [
            Cell(format_number(median), float(median)),
            Cell(f"{format_number(q1)}-{format_number(q3)}"),
            Cell(f"{format_number(ates.min())}-{format_number(ates.max())}"),
            Cell(f"{format_number(ates.mean())} +- {format_number(ates.std())}"),
        ]
    else:
        spread = [Cell("–") for _ in range(4)]
    return [Cell(str(len(runs))), *spread, Cell(failures_text(runs, dead)), Cell(f"{starved_runs} / {len(runs)}")]
