"""The report as Markdown (`report.md`, images in `report_files/`) and as one self-contained HTML
page (`report.html`, images embedded)."""

from __future__ import annotations

import base64
import html
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

from longslam.core.errors import InputError
from longslam.core.file_kinds import special_file_kind
from longslam.io.atomic import write_text_atomic
from longslam.run.process_tree import STARVED_SHARE, starved
from longslam.study.database import DB_NAME
from longslam.study.paper import CITATION
from longslam.study.report.distribution import FAILURE_RULE, distribution_table
from longslam.study.report.figures import Figure, make_figures
from longslam.study.report.results import load_results
from longslam.study.report.runs import RunsTable, every_run_table, runs_html, runs_markdown
from longslam.study.report.tables import (
    Table,
    _paper_columns,
    accuracy_table,
    field_table,
    map_table,
    memory_table,
    paper_tables,
    runs_table,
)


def _column_title(column: tuple[str, str]) -> str:
    route, noise = column
    return f"{route}: {noise}" if route else noise


def _row_cameras(table: Table) -> list[str] | None:
    """Each row's camera, for a table with a camera column; None for one without."""
    return table.row_cameras if table.row_cameras else None


def table_markdown(table: Table) -> str:
    has_metric = any(label[1] for label in table.row_labels)
    cameras = _row_cameras(table)
    header = (
        ["method"]
        + ([table.group_title] if cameras else [])
        + (["metric"] if has_metric else [])
        + [_column_title(c) for c in table.columns]
    )
    lines = [f"### {table.title}", "", table.caption, "", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    previous = previous_camera = None
    for i, ((method, metric), cells) in enumerate(zip(table.row_labels, table.rows)):
        shown = method if method != previous else ""
        lead = [shown]
        if cameras:
            camera = (method, cameras[i])
            lead.append(cameras[i] if camera != previous_camera else "")
            previous_camera = camera
        previous = method
        texts = [f"**{c.text}**" if c.best else c.text for c in cells]
        lines.append("| " + " | ".join(lead + ([metric] if has_metric else []) + texts) + " |")
    return "\n".join(lines) + "\n"


def _spans(keys: list) -> list[int]:
    """For rows grouped by `keys`: the number of rows a group spans at its first row, 0 after."""
    spans = [0] * len(keys)
    start = 0
    for i in range(1, len(keys) + 1):
        if i == len(keys) or keys[i] != keys[start]:
            spans[start] = i - start
            start = i
    return spans


def table_html(table: Table) -> str:
    esc = html.escape
    has_metric = any(label[1] for label in table.row_labels)
    cameras = _row_cameras(table)
    lead = 1 + bool(has_metric) + bool(cameras)
    routes: list[tuple[str, int]] = []
    for route, _ in table.columns:
        if routes and routes[-1][0] == route:
            routes[-1] = (route, routes[-1][1] + 1)
        else:
            routes.append((route, 1))
    parts = [
        f'<h3>{esc(table.title)}</h3><p class="caption">{esc(table.caption)}</p>'
        f'<table class="results" data-title="{esc(table.title)}"><thead>'
    ]
    if any(route for route, _ in routes):
        parts.append(
            f'<tr><th colspan="{lead}"></th>' + "".join(f'<th colspan="{n}">{esc(r)}</th>' for r, n in routes) + "</tr>"
        )
    parts.append(
        "<tr><th>method</th>"
        + (f"<th>{esc(table.group_title)}</th>" if cameras else "")
        + ("<th>metric</th>" if has_metric else "")
        + "".join(f"<th>{esc(noise)}</th>" for _, noise in table.columns)
        + "</tr></thead><tbody>"
    )
    counts: dict[str, int] = defaultdict(int)
    for method, _ in table.row_labels:
        counts[method] += 1
    camera_spans = _spans([(m, c) for (m, _), c in zip(table.row_labels, cameras)]) if cameras else []
    previous = None
    for i, ((method, metric), cells) in enumerate(zip(table.row_labels, table.rows)):
        row = "<tr>"
        if method != previous:
            row += f'<th rowspan="{counts[method]}" class="method">{esc(method)}</th>'
        previous = method
        if cameras and camera_spans[i]:
            row += f'<td rowspan="{camera_spans[i]}" class="camera">{esc(cameras[i])}</td>'
        if has_metric:
            row += f"<td class='metric'>{esc(metric)}</td>"
        row += "".join(_cell_html(c) for c in cells)
        parts.append(row + "</tr>")
    parts.append("</tbody></table>")
    return "".join(parts)


def _cell_html(cell) -> str:
    """A cell, in bold if best, linked to the rows of its runs if it has any."""
    text = html.escape(cell.text)
    if cell.best:
        text = f"<strong>{text}</strong>"
    if cell.link:
        text = f'<a class="cell" href="{html.escape(cell.link)}" title="the runs of this cell">{text}</a>'
    return f"<td>{text}</td>"


CSS = """
body { font-family: sans-serif; max-width: 1400px; margin: 2em auto; padding: 0 1em; color: #222; }
table.results { border-collapse: collapse; margin: 1em 0 2em; font-size: 13px; }
p.caption { font-size: 13px; max-width: 1000px; margin: .2em 0; }
h3 { margin: 1.5em 0 .3em; }
table.results th, table.results td { border: 1px solid #bbb; padding: 3px 8px; text-align: right; }
table.results th.method, table.results td.metric, table.results td.camera { text-align: left; }
table.results thead th { background: #eee; text-align: center; }
figure { margin: 1em 0 2em; } figure img { max-width: min(100%, 1100px); border: 1px solid #ddd; }
figcaption { font-size: 13px; color: #444; }
table.results a.cell { color: inherit; text-decoration: none; border-bottom: 1px dotted #888; }
table.runs td.id, table.runs td.status { text-align: left; } table.runs td.status.failed { color: #b00; }
table.runs td.files { text-align: left; white-space: nowrap; } table.runs tr:target { background: #ffd; }
div.plot { margin: 1em 0 .3em; max-width: 1100px; }
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
    runs: RunsTable | None = None  # every run, one row each


def _world_shown(world: str) -> str:
    """A world's name, or its mesh file's name and content hash."""
    from longslam.world.reference import MeshSpec, is_mesh_ref

    if not is_mesh_ref(world):
        return world
    spec = MeshSpec.from_ref(world)
    return f"`{Path(spec.path).name}` (mesh, sha256 {spec.sha256[:12]})"


def _camera_shown(camera: dict) -> str:
    return (
        f"{camera.get('width', '?')} x {camera.get('height', '?')}, {camera.get('hfov_deg', '?')} degree field "
        f"of view, depth to {camera.get('max_depth', '?')} m"
    )


E_ROT_NOTE = (
    "E_rot (Table 1) is the paper's: each frame's rotation error divided by that frame's travel, averaged. On "
    "short steps small per-frame jitter dominates it (a system that re-estimates each pose independently, as "
    "ORB-SLAM3 does, gets tens of deg/m from a fraction of a degree per frame); RPE rot in Table 1b, over "
    "travelled-distance segments, measures rotation drift."
)


def build_report(out: str | Path, figures: bool = True, left_out: list[str] | None = None) -> Report:
    results = load_results(out)
    config = results.config
    name = config.get("name", Path(out).name)
    seeds = config.get("seeds", [])
    counts = f"{len(results.ok)} runs ok, {len(results.runs) - len(results.ok)} failed, in `{DB_NAME}`."
    named = config.get("cameras")
    intro = [
        f"Study `{name}` ({config.get('source', '')}): world {_world_shown(config.get('world', '?'))}, "
        f"routes {', '.join(results.routes)}, noise levels {', '.join(results.noise)}, "
        f"methods {', '.join(results.methods)}, "
        + (f"sensors {', '.join(results.sensors)}, " if config.get("sensors") else "")
        + (f"perturbations {', '.join(results.perturbations)}, " if config.get("perturbations") else "")
        + f"seeds {', '.join(map(str, seeds))}.",
        (
            f"Cameras: {'; '.join(f'{n}: {_camera_shown(c)}' for n, c in named.items())}. {counts}"
            if named
            else f"Camera {_camera_shown(config.get('camera', {}))}. {counts}"
        ),
    ]
    tables = [accuracy_table(results), field_table(results), memory_table(results)]
    quality = map_table(results)
    if quality is not None:
        tables.append(quality)
    tables.append(runs_table(results))
    distribution = distribution_table(results)
    if distribution is not None:
        tables.append(distribution)
    notes = [E_ROT_NOTE]
    if distribution is not None:
        notes.append(FAILURE_RULE)
    starved_runs = [r["key"] for r in results.ok if starved(r.get("cpu_wait_share"))]
    if starved_runs:
        notes.append(
            f"{len(starved_runs)} run(s) waited for a CPU for more than {STARVED_SHARE:.0%} of their time (marked "
            "'starved' in All runs): their times, and for a real-time system their results, are not the "
            "system's own; `longslam study FILE --out DIR --retry-starved` runs them again."
        )
    if _paper_columns(results.columns):
        notes.append(
            f"Rows marked (paper) are the paper's own numbers for its route of the same length ({CITATION}); "
            "its building and systems differ from longslam's, so they are a reference, not a target."
        )
    if quality is None:
        notes.append(
            "No method of this study builds an occupancy grid, so there is no map quality table or map figure."
        )
    appendix = [] if _paper_columns(results.columns) else paper_tables()
    failures = [f"{r['key']}: {r['error']}" for r in results.runs if r["status"] != "ok"]
    missing: list[str] = []
    figs = make_figures(results, missing) if figures else []
    notes += [f"Left out: {m}." for m in missing]
    if left_out is not None:
        left_out.extend(missing)
    return Report(
        f"longslam study report: {name}", intro, tables, figs, failures, appendix, notes, every_run_table(results)
    )


def render_markdown(report: Report) -> str:
    parts = [f"# {report.title}", "", *report.intro, ""]
    parts += [table_markdown(t) for t in report.tables]
    if report.runs is not None:
        parts.append(runs_markdown(report.runs))
    parts += [f"- {n}" for n in report.notes] + [""] if report.notes else []
    if report.failures:
        parts += ["### Failed runs", ""] + [f"- `{f}`" for f in report.failures] + [""]
    if report.figures:
        parts += ["## Figures", ""]
        for fig in report.figures:
            parts += [f"![{fig.caption}]({fig.path.as_posix()})", "", f"*{fig.caption}*", ""]
    if report.appendix:
        parts += [
            "## The paper's numbers",
            "",
            "No route of this study is one of the paper's (paper-300m, paper-1km), so its numbers are given "
            "here as published, for reference.",
            "",
        ]
        parts += [table_markdown(t) for t in report.appendix]
    return "\n".join(parts).rstrip() + "\n"


def render_html(report: Report, out: Path) -> str:
    esc = html.escape
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{esc(report.title)}</title><style>{CSS}</style></head><body>",
        f"<h1>{esc(report.title)}</h1>",
    ]
    parts += [f"<p>{esc(p)}</p>" for p in report.intro]
    parts += ["<h2>Tables</h2>"] + [table_html(t) for t in report.tables]
    if report.runs is not None:
        parts.append(runs_html(report.runs))
    if report.notes:
        parts.append("<ul>" + "".join(f"<li>{esc(n)}</li>" for n in report.notes) + "</ul>")
    if report.failures:
        parts.append("<h3>Failed runs</h3><pre>" + esc("\n".join(report.failures)) + "</pre>")
    if report.figures:
        parts.append("<h2>Figures</h2>")
        if any(fig.interactive is not None for fig in report.figures):
            from longslam.study.report.interactive import plotly_js

            # plotly.js once, inline: the page works offline and from a file.
            parts.append(f'<script type="text/javascript">{plotly_js()}</script>')
        for i, fig in enumerate(report.figures):
            if fig.interactive is not None:
                from longslam.study.report.interactive import figure_div

                parts.append(
                    f'<figure class="interactive"><div class="plot">{figure_div(fig.interactive, f"figure-{i}")}</div>'
                    f"<figcaption>{esc(fig.caption)} Interactive: zoom, pan, hover; click a legend entry "
                    "to hide a line; where there are several seeds, the menu shows one or all."
                    "</figcaption></figure>"
                )
                continue
            data = base64.b64encode((out / fig.path).read_bytes()).decode("ascii")
            parts.append(
                f'<figure><img src="data:image/png;base64,{data}" alt="{esc(fig.caption)}">'
                f"<figcaption>{esc(fig.caption)}</figcaption></figure>"
            )
    if report.appendix:
        parts.append(
            "<h2>The paper's numbers</h2><p>No route of this study is one of the paper's (paper-300m, "
            "paper-1km), so its numbers are given here as published, for reference.</p>"
        )
        parts += [table_html(t) for t in report.appendix]
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"


REPORT_FILES = {"report.md": "# longslam study report", "report.html": "<title>longslam study report"}


def check_report_files(out: str | Path, overwrite: bool = False) -> None:
    """A report.md or report.html that longslam did not write (a user's own, recognised by its
    opening) is replaced only with `overwrite`; longslam's own report of the folder is rewritten."""
    for name, opening in REPORT_FILES.items():
        path = Path(out) / name
        if path.is_dir():
            raise InputError(f"{path} is a folder; the report needs that name for a file")
        kind = special_file_kind(path)
        if kind is not None:  # checked before the opening is read: reading a FIFO blocks
            raise InputError(f"{path} is {kind}, not a regular file; the report needs that name for a file")
        if path.exists() and not overwrite:
            try:
                with open(path, encoding="utf-8", errors="replace") as handle:
                    head = handle.read(4096)
            except OSError as err:
                raise InputError(f"{path} cannot be read to check it is longslam's report: {err.strerror}") from None
            if opening not in head:
                raise InputError(
                    f"{path} exists and is not a report longslam wrote; choose another folder, "
                    "move it, or pass --overwrite"
                )


def write_report(
    out: str | Path, figures: bool = True, overwrite: bool = False, left_out: list[str] | None = None
) -> Path:
    """Write DIR/report.md (+ DIR/report_files/*.png) and DIR/report.html; returns the HTML's path."""
    out = Path(out)
    check_report_files(out, overwrite)
    report = build_report(out, figures, left_out)
    write_text_atomic(out / "report.md", render_markdown(report))
    page = out / "report.html"
    write_text_atomic(page, render_html(report, out))
    return page
