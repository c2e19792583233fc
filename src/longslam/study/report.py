"""The study report: the paper's two tables reproduced from the results database, beside the
paper's own numbers, and the figures; as Markdown (`report.md`, images in `report_files/`) and
as one self-contained HTML page (`report.html`, images embedded).

Table 1: E_trans, E_rot (deg/m) and ATE (m), mean +- std over the seeds, per method, route and
noise level. Table 2: peak resident memory (GB) of the process that ran the method. The best
value of each column is in bold (lower is better; for map quality, higher). The paper's rows
(RTAB-Map, Voxgraph) stand beside ours for the routes that are the paper's (paper-300m, paper-1km).
"""

from __future__ import annotations

import base64
import html
import math
import re
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from longslam.errors import InputError
from longslam.io.atomic import write_text_atomic
from longslam.study.database import DB_NAME, ResultsDB
from longslam.study.paper import (
    ACCURACY_METRICS, CITATION, PAPER_METHODS, PAPER_NOISE, PAPER_ROUTES, paper_accuracy, paper_memory_gb, paper_route,
)

METRIC_LABELS = {"e_trans": "E_trans", "e_rot": "E_rot [deg/m]", "ate": "ATE [m]"}
FIGURES_DIR = "report_files"


# ----------------------------------------------------------------------------- numbers


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


def format_mean_std(values: list[float]) -> str:
    """'mean ± std' (sample std over the runs): three significant digits on the mean, two on the std;
    the mean alone for one value, '–' for none."""
    values = [v for v in values if v is not None and math.isfinite(v)]
    if not values:
        return "–"
    mean = float(np.mean(values))
    if len(values) == 1:
        return format_number(mean)
    return f"{format_number(mean)} ± {format_number(float(np.std(values, ddof=1)), 2)}"


@dataclass
class Cell:
    text: str
    value: float | None = None  # the mean, for choosing the best
    best: bool = False


@dataclass
class Table:
    title: str
    caption: str
    columns: list[tuple[str, str]]  # (route, noise)
    row_labels: list[tuple[str, str]]  # (method, metric); metric may be ""
    rows: list[list[Cell]] = field(default_factory=list)

    def mark_best(self, higher_is_better: bool = False) -> None:
        """Bold the best mean of each column among the rows of each metric."""
        metrics = {label[1] for label in self.row_labels}
        for metric in metrics:
            indices = [i for i, label in enumerate(self.row_labels) if label[1] == metric]
            for c in range(len(self.columns)):
                values = [(self.rows[i][c].value, i) for i in indices if self.rows[i][c].value is not None]
                if len(values) < 2:
                    continue
                best = max(values)[0] if higher_is_better else min(values)[0]
                for value, i in values:  # equal as shown is equal
                    self.rows[i][c].best = format_number(value) == format_number(best)


# ----------------------------------------------------------------------------- gathering


@dataclass
class StudyResults:
    out: Path
    config: dict[str, Any]
    runs: list[dict[str, Any]]  # every recorded run
    ok: list[dict[str, Any]]
    routes: list[str]
    noise: list[str]
    methods: list[str]

    @property
    def columns(self) -> list[tuple[str, str]]:
        present = {(r["route"], r["noise"]) for r in self.runs}
        return [(route, noise) for route in self.routes for noise in self.noise if (route, noise) in present]

    def values(self, method: str, route: str, noise: str, column: str) -> list[float]:
        return [r[column] for r in self.ok if (r["method"], r["route"], r["noise"]) == (method, route, noise) and r[column] is not None]


def _ordered(first: list[str], seen: list[str]) -> list[str]:
    out = [x for x in first if x in seen]
    return out + sorted(set(seen) - set(out))


def load_results(out: str | Path) -> StudyResults:
    out = Path(out)
    path = out / DB_NAME
    if not path.is_file():
        raise InputError(f"{out} holds no study results ({DB_NAME} is missing); run `longslam study FILE --out {out}` first")
    with ResultsDB(path) as db:
        config = db.study() or {}
        runs = db.runs()
    ok = [r for r in runs if r["status"] == "ok"]
    routes = _ordered([r["name"] for r in config.get("routes", [])], [r["route"] for r in runs])
    noise = _ordered(list(config.get("noise", [])), [r["noise"] for r in runs])
    methods = _ordered([m["label"] for m in config.get("methods", [])], [r["method"] for r in runs])
    return StudyResults(out, config, runs, ok, routes, noise, methods)


# ----------------------------------------------------------------------------- tables


def _paper_columns(columns: list[tuple[str, str]]) -> bool:
    return any(paper_route(route) and noise in PAPER_NOISE for route, noise in columns)


def accuracy_table(results: StudyResults) -> Table:
    columns = results.columns
    table = Table(
        "Table 1: accuracy",
        "E_trans (unitless), E_rot (deg/m) and ATE (m, no alignment): mean ± std over the seeds; "
        "lower is better, the best of each column in bold.",
        columns, [],
    )
    for method in results.methods:
        for metric in ACCURACY_METRICS:
            cells = []
            for route, noise in columns:
                values = results.values(method, route, noise, metric)
                cells.append(Cell(format_mean_std(values), float(np.mean(values)) if values else None))
            table.row_labels.append((method, METRIC_LABELS[metric]))
            table.rows.append(cells)
    if _paper_columns(columns):
        numbers = paper_accuracy()
        for key, name in PAPER_METHODS.items():
            for metric in ACCURACY_METRICS:
                cells = []
                for route, noise in columns:
                    value = numbers.get((key, paper_route(route) or "", noise, metric))
                    cells.append(Cell(value.text, value.mean) if value else Cell("–"))
                table.row_labels.append((f"{name} (paper)", METRIC_LABELS[metric]))
                table.rows.append(cells)
    table.mark_best()
    return table


def memory_table(results: StudyResults) -> Table:
    columns = results.columns
    table = Table(
        "Table 2: peak memory",
        "Peak resident memory (GB) of the process that ran the method, measured from outside it; "
        "mean ± std over the seeds; lower is better, the best of each column in bold.",
        columns, [],
    )
    for method in results.methods:
        cells = []
        for route, noise in columns:
            values = [v / 1e9 for v in results.values(method, route, noise, "peak_rss_bytes")]
            cells.append(Cell(format_mean_std(values), float(np.mean(values)) if values else None))
        table.row_labels.append((method, ""))
        table.rows.append(cells)
    if _paper_columns(columns):
        numbers = paper_memory_gb()
        for key, name in PAPER_METHODS.items():
            cells = []
            for route, noise in columns:
                value = numbers.get((key, paper_route(route) or "", noise))
                cells.append(Cell(value.text, value.mean) if value else Cell("–"))
            table.row_labels.append((f"{name} (paper)", ""))
            table.rows.append(cells)
    table.mark_best()
    return table


def map_table(results: StudyResults) -> Table | None:
    with_maps = [m for m in results.methods if any(r["map_precision"] is not None for r in results.ok if r["method"] == m)]
    if not with_maps:
        return None
    tolerance = results.config.get("map_tolerance_cells", 2)
    table = Table(
        "Table 3: map quality",
        f"Occupied cells of each method's 2D grid against the ground-truth grid, within {tolerance:g} cells "
        "(of the coarser grid): precision (a fake corridor lowers it) and recall of the walls the camera "
        "could see; mean ± std over the seeds; higher is better.",
        results.columns, [],
    )
    for method in with_maps:
        for column, label in (("map_precision", "precision"), ("map_recall", "recall")):
            cells = []
            for route, noise in results.columns:
                values = results.values(method, route, noise, column)
                cells.append(Cell(format_mean_std(values), float(np.mean(values)) if values else None))
            table.row_labels.append((method, label))
            table.rows.append(cells)
    table.mark_best(higher_is_better=True)
    return table


def runs_table(results: StudyResults) -> Table:
    table = Table(
        "Runs",
        "Runs recorded per method (ok / failed); mean over the successful runs of: the time of a run "
        "(its process from start to end: start-up, reading frames, the method, scoring), the method's "
        "own processing time, the real-time factor (simulated seconds per second of the method's "
        "processing) and the frames per run.",
        [("", "runs ok / failed"), ("", "time per run [s]"), ("", "method time [s]"), ("", "real-time factor"), ("", "frames")], [],
    )
    for method in results.methods:
        mine = [r for r in results.runs if r["method"] == method]
        ok = [r for r in mine if r["status"] == "ok"]
        def mean(column: str) -> str:
            values = [r[column] for r in ok if r.get(column) is not None]
            return format_number(float(np.mean(values))) if values else "–"
        table.row_labels.append((method, ""))
        table.rows.append([Cell(f"{len(ok)} / {len(mine) - len(ok)}"), Cell(mean("elapsed_s")), Cell(mean("method_time_s")),
                           Cell(mean("real_time_factor")), Cell(mean("frames"))])
    return table


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
    memory = Table("The paper's Table 2 as published", f"{CITATION}, Table 2: memory (GB).", columns, [])
    mem = paper_memory_gb()
    for key, name in PAPER_METHODS.items():
        memory.row_labels.append((name, ""))
        memory.rows.append([Cell(mem[(key, route, noise)].text, mem[(key, route, noise)].mean) for route, noise in columns])
    memory.mark_best()
    return [accuracy, memory]


# ----------------------------------------------------------------------------- figures


@dataclass
class Figure:
    path: Path  # relative to the study folder
    caption: str


def _first_seed_runs(results: StudyResults, route: str, noise: str) -> dict[str, dict]:
    chosen: dict[str, dict] = {}
    for run in sorted(results.ok, key=lambda r: r["seed"]):
        if (run["route"], run["noise"]) == (route, noise) and run["method"] not in chosen:
            chosen[run["method"]] = run
    return {m: chosen[m] for m in results.methods if m in chosen}


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name)


def make_figures(results: StudyResults) -> list[Figure]:
    from longslam.gridmap import GridMap
    from longslam.io.trajectory_files import read_tum
    from longslam.study.plots import plot_curves_by_distance, plot_maps, plot_plan
    from longslam.study.prepare import load_route_data, load_world_grid

    out = results.out
    folder = out / FIGURES_DIR
    folder.mkdir(parents=True, exist_ok=True)
    for old in folder.glob("*.png"):
        old.unlink()
    figures: list[Figure] = []
    world = results.config.get("world", "university")
    try:
        truth_grid = load_world_grid(out, world)
    except InputError:
        return figures
    for route in results.routes:
        try:
            data = load_route_data(out, route)
        except (OSError, InputError):
            continue
        truth_xy = data.truth.positions[:, :2]
        noises = [n for n in results.noise if any(r["route"] == route and r["noise"] == n for r in results.ok)]
        for noise in noises:
            runs = _first_seed_runs(results, route, noise)
            paths = {"ground truth": truth_xy}
            seeds = set()
            for method, run in runs.items():
                try:
                    paths[f"{method}"] = read_tum(out / run["trajectory_path"]).positions[:, :2]
                    seeds.add(run["seed"])
                except (OSError, InputError, TypeError):
                    continue
            name = Path(FIGURES_DIR) / f"trajectories-{_safe(route)}-{_safe(noise)}.png"
            seed_text = ", ".join(str(s) for s in sorted(seeds))
            plot_plan(truth_grid, out / name, paths, waypoints=data.waypoints, zoom_margin=6.0,
                      title=f"route {route} ({data.length_m:.0f} m), noise {noise}, seed {seed_text}")
            figures.append(Figure(name, f"Estimated trajectories over the floor plan with the ground truth: route {route}, noise {noise}, seed {seed_text}."))

        for column, ylabel, scale, what in (
            ("error_curve", "position error [m]", 1.0, "ATE (position error, no alignment)"),
            ("memory_curve", "resident memory [MB]", 1e-6, "Resident memory of the run's process"),
        ):
            panels: dict[str, dict[str, list[np.ndarray]]] = {}
            for noise in noises:
                curves: dict[str, list[np.ndarray]] = defaultdict(list)
                for run in results.ok:
                    if (run["route"], run["noise"]) == (route, noise) and run[column]:
                        curve = np.asarray(run[column], dtype=np.float64)
                        curve[:, 1] *= scale
                        curves[run["method"]].append(curve)
                panels[f"noise {noise}"] = {m: curves[m] for m in results.methods if m in curves}
            if any(panels.values()):
                kind = "ate" if column == "error_curve" else "memory"
                name = Path(FIGURES_DIR) / f"{kind}-{_safe(route)}.png"
                plot_curves_by_distance(panels, out / name, ylabel, title=f"route {route}")
                figures.append(Figure(name, f"{what} against distance travelled, route {route}: mean over the seeds, band from the lowest to the highest run."))

        # The maps are shown over the walls the camera could see from the route, and the route.
        seen = truth_grid.cell_to_world(np.argwhere(data.observed)) if data.observed.shape == truth_grid.data.shape else np.zeros((0, 2))
        extent = np.vstack([truth_xy, seen])
        lo, hi = extent.min(axis=0) - 1.0, extent.max(axis=0) + 1.0
        view = (lo[0], hi[0], lo[1], hi[1])
        for noise in noises:
            maps, captions = {}, {}
            for method, run in _first_seed_runs(results, route, noise).items():
                if not run.get("grid_path"):
                    continue
                try:
                    maps[method] = GridMap.load(out / run["grid_path"])
                except InputError:
                    continue
                p, r = run.get("map_precision"), run.get("map_recall")
                captions[method] = f"precision {p:.2f}, recall {r:.2f}" if p is not None and r is not None else ""
            if maps:
                name = Path(FIGURES_DIR) / f"maps-{_safe(route)}-{_safe(noise)}.png"
                plot_maps(truth_grid, maps, out / name, view=view, path=truth_xy, captions=captions,
                          title=f"occupancy maps, route {route}, noise {noise}, first seed")
                figures.append(Figure(name, f"Each method's occupancy grid beside the ground truth: route {route}, noise {noise} (first seed)."))
    return figures


# ----------------------------------------------------------------------------- rendering


def _column_title(column: tuple[str, str]) -> str:
    route, noise = column
    return f"{route}: {noise}" if route else noise


def table_markdown(table: Table) -> str:
    has_metric = any(label[1] for label in table.row_labels)
    header = ["method"] + (["metric"] if has_metric else []) + [_column_title(c) for c in table.columns]
    lines = [f"### {table.title}", "", table.caption, "", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    previous = None
    for (method, metric), cells in zip(table.row_labels, table.rows):
        shown = method if method != previous else ""
        previous = method
        texts = [f"**{c.text}**" if c.best else c.text for c in cells]
        lines.append("| " + " | ".join([shown] + ([metric] if has_metric else []) + texts) + " |")
    return "\n".join(lines) + "\n"


def table_html(table: Table) -> str:
    esc = html.escape
    has_metric = any(label[1] for label in table.row_labels)
    lead = 2 if has_metric else 1
    routes: list[tuple[str, int]] = []
    for route, _ in table.columns:
        if routes and routes[-1][0] == route:
            routes[-1] = (route, routes[-1][1] + 1)
        else:
            routes.append((route, 1))
    parts = [f'<h3>{esc(table.title)}</h3><p class="caption">{esc(table.caption)}</p>'
             f'<table class="results" data-title="{esc(table.title)}"><thead>']
    if any(route for route, _ in routes):
        parts.append(f'<tr><th colspan="{lead}"></th>' + "".join(f'<th colspan="{n}">{esc(r)}</th>' for r, n in routes) + "</tr>")
    parts.append("<tr><th>method</th>" + ("<th>metric</th>" if has_metric else "")
                 + "".join(f"<th>{esc(noise)}</th>" for _, noise in table.columns) + "</tr></thead><tbody>")
    counts: dict[str, int] = defaultdict(int)
    for method, _ in table.row_labels:
        counts[method] += 1
    previous = None
    for (method, metric), cells in zip(table.row_labels, table.rows):
        row = "<tr>"
        if method != previous:
            row += f'<th rowspan="{counts[method]}" class="method">{esc(method)}</th>'
        previous = method
        if has_metric:
            row += f"<td class='metric'>{esc(metric)}</td>"
        row += "".join(f"<td><strong>{esc(c.text)}</strong></td>" if c.best else f"<td>{esc(c.text)}</td>" for c in cells)
        parts.append(row + "</tr>")
    parts.append("</tbody></table>")
    return "".join(parts)


CSS = """
body { font-family: sans-serif; max-width: 1400px; margin: 2em auto; padding: 0 1em; color: #222; }
table.results { border-collapse: collapse; margin: 1em 0 2em; font-size: 13px; }
p.caption { font-size: 13px; max-width: 1000px; margin: .2em 0; }
h3 { margin: 1.5em 0 .3em; }
table.results th, table.results td { border: 1px solid #bbb; padding: 3px 8px; text-align: right; }
table.results th.method, table.results td.metric { text-align: left; }
table.results thead th { background: #eee; text-align: center; }
figure { margin: 1em 0 2em; } figure img { max-width: min(100%, 1100px); border: 1px solid #ddd; }
figcaption { font-size: 13px; color: #444; }
pre { background: #f6f6f6; padding: .6em; overflow-x: auto; font-size: 12px; }
"""


@dataclass
class Report:
    title: str
    intro: list[str]
    tables: list[Table]
    figures: list[Figure]
    failures: list[str]
    appendix: list[Table]
    notes: list[str]


def build_report(out: str | Path, figures: bool = True) -> Report:
    results = load_results(out)
    config = results.config
    name = config.get("name", Path(out).name)
    seeds = config.get("seeds", [])
    camera = config.get("camera", {})
    intro = [
        f"Study `{name}` ({config.get('source', '')}): world {config.get('world', '?')}, "
        f"routes {', '.join(results.routes)}, noise levels {', '.join(results.noise)}, "
        f"methods {', '.join(results.methods)}, seeds {', '.join(map(str, seeds))}.",
        f"Camera {camera.get('width', '?')} x {camera.get('height', '?')}, {camera.get('hfov_deg', '?')} degree field "
        f"of view, depth to {camera.get('max_depth', '?')} m. {len(results.ok)} runs ok, "
        f"{len(results.runs) - len(results.ok)} failed, in `{DB_NAME}`.",
    ]
    tables = [accuracy_table(results), memory_table(results)]
    quality = map_table(results)
    if quality is not None:
        tables.append(quality)
    tables.append(runs_table(results))
    notes = []
    if _paper_columns(results.columns):
        notes.append(f"Rows marked (paper) are the paper's own numbers for its route of the same length ({CITATION}); "
                     "its building and systems differ from longslam's, so they are a reference, not a target.")
    if quality is None:
        notes.append("No method of this study builds an occupancy grid, so there is no map quality table or map figure.")
    appendix = [] if _paper_columns(results.columns) else paper_tables()
    failures = [f"{r['key']}: {r['error']}" for r in results.runs if r["status"] != "ok"]
    figs = make_figures(results) if figures else []
    return Report(f"longslam study report: {name}", intro, tables, figs, failures, appendix, notes)


def render_markdown(report: Report) -> str:
    parts = [f"# {report.title}", "", *report.intro, ""]
    parts += [table_markdown(t) for t in report.tables]
    parts += [f"- {n}" for n in report.notes] + [""] if report.notes else []
    if report.failures:
        parts += ["### Failed runs", ""] + [f"- `{f}`" for f in report.failures] + [""]
    if report.figures:
        parts += ["## Figures", ""]
        for fig in report.figures:
            parts += [f"![{fig.caption}]({fig.path.as_posix()})", "", f"*{fig.caption}*", ""]
    if report.appendix:
        parts += ["## The paper's numbers", "",
                  "No route of this study is one of the paper's (paper-300m, paper-1km), so its numbers are given "
                  "here as published, for reference.", ""]
        parts += [table_markdown(t) for t in report.appendix]
    return "\n".join(parts).rstrip() + "\n"


def render_html(report: Report, out: Path) -> str:
    esc = html.escape
    parts = [
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{esc(report.title)}</title><style>{CSS}</style></head><body>",
        f"<h1>{esc(report.title)}</h1>",
    ]
    parts += [f"<p>{esc(p)}</p>" for p in report.intro]
    parts += ["<h2>Tables</h2>"] + [table_html(t) for t in report.tables]
    if report.notes:
        parts.append("<ul>" + "".join(f"<li>{esc(n)}</li>" for n in report.notes) + "</ul>")
    if report.failures:
        parts.append("<h3>Failed runs</h3><pre>" + esc("\n".join(report.failures)) + "</pre>")
    if report.figures:
        parts.append("<h2>Figures</h2>")
        for fig in report.figures:
            data = base64.b64encode((out / fig.path).read_bytes()).decode("ascii")
            parts.append(f'<figure><img src="data:image/png;base64,{data}" alt="{esc(fig.caption)}">'
                         f"<figcaption>{esc(fig.caption)}</figcaption></figure>")
    if report.appendix:
        parts.append("<h2>The paper's numbers</h2><p>No route of this study is one of the paper's (paper-300m, "
                     "paper-1km), so its numbers are given here as published, for reference.</p>")
        parts += [table_html(t) for t in report.appendix]
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"


def write_report(out: str | Path, figures: bool = True) -> Path:
    """Write DIR/report.md (+ DIR/report_files/*.png) and DIR/report.html; returns the HTML's path."""
    out = Path(out)
    report = build_report(out, figures)
    write_text_atomic(out / "report.md", render_markdown(report))
    page = out / "report.html"
    write_text_atomic(page, render_html(report, out))
    return page
