"""The report's tables: Table 1 (accuracy) and Table 2 (memory) beside the paper's numbers, map
quality, the runs, and the paper's tables as published; numbers formatted the one way."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from longslam.run.process_tree import starved
from longslam.run.speed import format_real_time_factor
from longslam.study.paper import (
    ACCURACY_METRICS,
    CITATION,
    PAPER_METHODS,
    PAPER_NOISE,
    PAPER_ROUTES,
    paper_accuracy,
    paper_memory_gb,
    paper_route,
)
from longslam.study.report.results import RowGroup, StudyResults, on_camera, runs_anchor

METRIC_LABELS = {"e_trans": "E_trans", "e_rot": "E_rot [deg/m]", "ate": "ATE [m]"}


def format_number(value: float, significant: int = 3) -> str:
    """A number with `significant` digits ('0.0487', '4.14', '10.6'), whole above 10**significant."""
    if value == 0:
        return "0"
    if abs(value) >= 10**significant:
        return f"{value:.0f}"
    if abs(value) < 1e-6:
        return f"{value:.{significant - 1}e}"
    decimals = max(0, significant - 1 - math.floor(math.log10(abs(value))))
    return f"{value:.{decimals}f}"


def _decimals(value: float, significant: int = 3) -> int:
    """Decimal places that show `value` with `significant` digits (0 for whole numbers above that)."""
    if value == 0 or not math.isfinite(value):
        return 0
    return max(0, significant - 1 - math.floor(math.log10(abs(value))))


def format_mean_std(values: list[float]) -> str:
    """'mean ± std (n=N)' (sample std over the N runs): three significant digits on the mean and the
    std to the same decimal place, so the two read alike ('1.00 ± 0.00', '0.00943 ± 0.00010');
    'mean (n=1)' for one value, '–' for none."""
    values = [v for v in values if v is not None and math.isfinite(v)]
    if not values:
        return "–"
    mean = float(np.mean(values))
    n = f"(n={len(values)})"
    if len(values) == 1:
        return f"{format_number(mean)} {n}"
    std = float(np.std(values, ddof=1))
    # A mean of exactly 0 (every run 0 but one) has no digits of its own: the std's decide.
    places = _decimals(mean) if mean != 0 else _decimals(std, 2)
    return f"{mean:.{places}f} ± {std:.{places}f} {n}"


@dataclass
class Cell:
    text: str
    value: float | None = None  # the mean, for choosing the best
    best: bool = False
    link: str | None = None  # in the HTML page: the rows of the runs behind the cell ("#runs-...")


@dataclass
class Table:
    title: str
    caption: str
    columns: list[tuple[str, str]]  # (route, noise)
    row_labels: list[tuple[str, str]]  # (method, metric); metric may be ""
    rows: list[list[Cell]] = field(default_factory=list)
    # Each row's camera, in a study with several ("" for the paper's rows); empty otherwise, and
    # then the table has no camera column.
    row_cameras: list[str] = field(default_factory=list)
    group_title: str = "camera"  # the heading of that column: camera, sensor, or camera, sensor

    def add_row(self, label: tuple[str, str], cells: list[Cell], camera: object | None = None) -> None:
        """One row; `camera` is its camera's name or row group (shown as text), None for none."""
        self.row_labels.append(label)
        self.rows.append(cells)
        if camera is not None or self.row_cameras:
            self.row_cameras += [""] * (len(self.rows) - 1 - len(self.row_cameras)) + [
                "" if camera is None else str(camera)
            ]

    def mark_best(self, higher_is_better: bool = False, reversed_metrics: tuple[str, ...] = ()) -> None:
        """Bold the best mean of each column among the rows of each metric (the metrics named in
        `reversed_metrics` go the other way)."""
        metrics = {label[1] for label in self.row_labels}
        for metric in metrics:
            higher = higher_is_better != (metric in reversed_metrics)
            indices = [i for i, label in enumerate(self.row_labels) if label[1] == metric]
            for c in range(len(self.columns)):
                values = [(v, i) for i in indices if (v := self.rows[i][c].value) is not None]
                if len(values) < 2:
                    continue
                best = max(values)[0] if higher else min(values)[0]
                for value, i in values:  # equal as shown is equal
                    self.rows[i][c].best = format_number(value) == format_number(best)


def _paper_columns(columns: list[tuple[str, str]]) -> bool:
    return any(paper_route(route) and noise in PAPER_NOISE for route, noise in columns)


def _our_cells(
    results: StudyResults, method: str, column: str, scale: float = 1.0, camera: RowGroup | str | None = None
) -> list[Cell]:
    """A method's mean ± std of one database column (of one camera's runs if `camera` is given),
    per (route, noise) column of the table."""
    cells = []
    for route, noise in results.columns:
        values = [scale * v for v in results.values(method, route, noise, column, camera)]
        cells.append(
            Cell(
                format_mean_std(values),
                float(np.mean(values)) if values else None,
                link=f"#{runs_anchor(route, noise, method, camera)}" if values else None,
            )
        )
    return cells


def _paper_cells(columns: list[tuple[str, str]], lookup) -> list[Cell]:
    """The paper's published value per column ('–' where it has none); lookup(route, noise)."""
    cells = []
    for route, noise in columns:
        value = lookup(paper_route(route) or "", noise)
        cells.append(Cell(value.text, value.mean) if value else Cell("–"))
    return cells


def _comparison_table(
    results: StudyResults, title: str, caption: str, metrics: list[tuple[str, str, float]], paper_numbers
) -> Table:
    """One row per (method, metric): ours (mean ± std of a database column times a scale), then
    the paper's published rows where the table has the paper's routes. `paper_numbers()` gives
    {(paper method, route, noise, column): value}."""
    columns = results.columns
    table = Table(title, caption, columns, [], group_title=results.group_title or "camera")
    for method in results.methods:
        for camera in results.row_cameras:
            if not _has_runs(results, method, camera):
                continue
            for column, label, scale in metrics:
                table.add_row((method, label), _our_cells(results, method, column, scale, camera), camera)
    if _paper_columns(columns):
        numbers = paper_numbers()
        for key, name in PAPER_METHODS.items():
            for column, label, _ in metrics:
                cells = _paper_cells(
                    columns, lambda route, noise, key=key, column=column: numbers.get((key, route, noise, column))
                )
                if any(c.value is not None for c in cells):  # the paper has no APE or RPE
                    table.add_row((f"{name} (paper)", label), cells)
    table.mark_best()
    return table


def _has_runs(results: StudyResults, method: str, camera: RowGroup | str | None) -> bool:
    """A method has rows for every camera it ran with (a camera it never ran with, none)."""
    return camera is None or any(r["method"] == method and on_camera(r, camera) for r in results.runs)


def accuracy_table(results: StudyResults) -> Table:
    return _comparison_table(
        results,
        "Table 1: accuracy",
        "E_trans (unitless), E_rot (deg/m) and ATE (m, no alignment): mean ± std over the n seeds; "
        "lower is better, the best of each column in bold.",
        [(metric, METRIC_LABELS[metric], 1.0) for metric in ACCURACY_METRICS],
        paper_accuracy,
    )


FIELD_METRICS = (("ape_rmse", "APE RMSE [m]"), ("rpe_trans", "RPE trans RMSE [m]"), ("rpe_rot", "RPE rot RMSE [deg]"))


def field_table(results: StudyResults) -> Table:
    """The field's metrics (as evo computes them) of each method: the paper has no such numbers."""
    align = results.config.get("align", "none")
    return _comparison_table(
        results,
        "Table 1b: APE and RPE",
        f"The field's standard metrics, as evo computes them (alignment: {align}): APE RMSE (m) of the "
        "positions; RPE RMSE over consecutive 1 m segments of ground-truth path, translation (m) and "
        "rotation (deg); mean ± std over the n seeds; lower is better, the best of each column in bold.",
        [(metric, label, 1.0) for metric, label in FIELD_METRICS],
        lambda: {},
    )


def _paper_memory_mb() -> dict:
    """The paper's Table 2 (GB) in MB, the one memory unit of the report and the CLI."""
    from longslam.study.paper import PaperValue

    return {
        (*key, "peak_rss_bytes"): PaperValue(1000 * value.mean, None, format_number(1000 * value.mean))
        for key, value in paper_memory_gb().items()
    }


def memory_table(results: StudyResults) -> Table:
    return _comparison_table(
        results,
        "Table 2: peak memory",
        "Peak resident memory (MB, 10^6 bytes) of the run: the highest VmHWM of the run's own process, "
        "which runs nothing but that run, read by longslam's harness inside that process once the "
        "method has finished and its files are written (so Python, the frame reader and writing the "
        "files are in it; the scoring after is not); mean ± std over the n seeds; lower is better, the best of "
        "each column in bold. "
        "The paper's rows are its Table 2 (GB) in MB.",
        [("peak_rss_bytes", "", 1e-6)],
        _paper_memory_mb,
    )


MAP_ROWS = (
    ("map_precision", "precision"),
    ("map_recall", "recall"),
    ("map_precision_aligned", "precision, aligned"),
    ("map_recall_aligned", "recall, aligned"),
    ("map_doubled_walls", "doubled walls"),
)


def map_table(results: StudyResults) -> Table | None:
    with_maps = [
        m for m in results.methods if any(r["map_precision"] is not None for r in results.ok if r["method"] == m)
    ]
    if not with_maps:
        return None
    tolerance = results.config.get("map_tolerance_cells", 2)
    table = Table(
        "Table 3: map quality",
        f"Occupied cells of each method's 2D grid against the ground-truth grid, within {tolerance:g} cells "
        "(of the coarser grid): precision and recall of the walls the camera could see, as the map is and "
        "after its best planar (x, y, yaw) alignment to the ground truth (a map that drifted as a whole "
        "loses only the first pair), and the share of those walls the aligned map shows twice, a corridor "
        "width apart (a fake corridor; lower is better); mean ± std over the seeds; the best of each "
        "column in bold.",
        results.columns,
        [],
        group_title=results.group_title or "camera",
    )
    for method in with_maps:
        for camera in results.row_cameras:
            if not _has_runs(results, method, camera):
                continue
            for column, label in MAP_ROWS:
                cells = []
                for route, noise in results.columns:
                    values = [
                        v
                        for r in results.ok
                        if (r["method"], r["route"], r["noise"]) == (method, route, noise)
                        and on_camera(r, camera)
                        and (v := r.get(column)) is not None
                    ]  # studies recorded before a column have none
                    cells.append(
                        Cell(
                            format_mean_std(values),
                            float(np.mean(values)) if values else None,
                            link=f"#{runs_anchor(route, noise, method, camera)}" if values else None,
                        )
                    )
                if label != "precision" and label != "recall" and all(c.value is None for c in cells):
                    continue
                table.add_row((method, label), cells, camera)
    table.mark_best(higher_is_better=True, reversed_metrics=("doubled walls",))
    return table


def runs_table(results: StudyResults) -> Table:
    table = Table(
        "Runs",
        "Runs recorded per method (ok / failed); mean over the successful runs of: the time of a run "
        "(its process from start to end: start-up, reading frames, the method, scoring), the method's "
        "own processing time, the real-time factor (simulated seconds per second of the method's "
        "processing) and the frames per run; and the runs starved of CPU (their threads waited for a core for "
        "more than 10% of their time) with the largest CPU wait share.",
        [
            ("", "runs ok / failed"),
            ("", "time per run [s]"),
            ("", "method time [s]"),
            ("", "real-time factor"),
            ("", "frames"),
            ("", "starved"),
            ("", "CPU wait share, max"),
        ],
        [],
        group_title=results.group_title or "camera",
    )
    for method in results.methods:
        for camera in results.row_cameras:
            mine = [r for r in results.runs if r["method"] == method and on_camera(r, camera)]
            if not mine:
                continue
            ok = [r for r in mine if r["status"] == "ok"]

            def mean(column: str, form=format_number, ok=ok) -> str:
                values = [r[column] for r in ok if r.get(column) is not None]
                return form(float(np.mean(values))) if values else "–"

            table.add_row(
                (method, ""),
                [
                    Cell(f"{len(ok)} / {len(mine) - len(ok)}"),
                    Cell(mean("elapsed_s")),
                    Cell(mean("method_time_s")),
                    Cell(mean("real_time_factor", format_real_time_factor)),
                    Cell(mean("frames")),
                    Cell(_starved(ok)),
                    Cell(_max(ok, "cpu_wait_share")),
                ],
                camera,
            )
    return table


def _starved(runs: list[dict]) -> str:
    measured = [r for r in runs if r.get("cpu_wait_share") is not None]
    if not measured:
        return "–"
    return f"{sum(1 for r in measured if starved(r['cpu_wait_share']))} / {len(measured)}"


def _max(runs: list[dict], column: str) -> str:
    values = [r[column] for r in runs if r.get(column) is not None]
    return format_number(float(max(values))) if values else "–"


def paper_tables() -> list[Table]:
    """The paper's Tables 1 and 2 as published."""
    columns = [(route, noise) for route in PAPER_ROUTES.values() for noise in PAPER_NOISE]
    accuracy = Table("The paper's Table 1 as published", f"{CITATION}, Table 1 (mean ± std over 5 runs).", columns, [])
    numbers = paper_accuracy()
    for key, name in PAPER_METHODS.items():
        for metric in ACCURACY_METRICS:
            cells = []
            for route, noise in columns:
                value = numbers[(key, route, noise, metric)]
                cells.append(Cell(value.text, value.mean))
            accuracy.row_labels.append((name, METRIC_LABELS[metric]))
            accuracy.rows.append(cells)
    accuracy.mark_best()
    memory = Table(
        "The paper's Table 2 as published",
        f"{CITATION}, Table 2: memory, in MB (the paper gives GB) like every memory figure of this report.",
        columns,
        [],
    )
    mem = _paper_memory_mb()
    for key, name in PAPER_METHODS.items():
        memory.row_labels.append((name, ""))
        memory.rows.append(
            [
                Cell(mem[(key, route, noise, "peak_rss_bytes")].text, mem[(key, route, noise, "peak_rss_bytes")].mean)
                for route, noise in columns
            ]
        )
    memory.mark_best()
    return [accuracy, memory]
