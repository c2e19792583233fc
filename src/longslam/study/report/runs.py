"""The report's table of every run: one row per recorded run, with each metric, its peak memory,
time and status, and links to the files of its folder and to its log (when the log holds
anything); a cell of Tables 1 to 3 links to its runs' rows (`runs_anchor`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from longslam.run.console import CONSOLE_LOG
from longslam.run.folder import CONFIG, STATS, TRAJECTORY
from longslam.run.process_tree import STARVED_SHARE, starved
from longslam.study.report.results import StudyResults, runs_anchor
from longslam.study.report.tables import format_number

# (database column, heading, scale): every metric of a run that has a column of its own.
METRICS = (
    ("ate", "ATE [m]", 1.0),
    ("e_trans", "E_trans", 1.0),
    ("e_rot", "E_rot [deg/m]", 1.0),
    ("ape_rmse", "APE RMSE [m]", 1.0),
    ("rpe_trans", "RPE trans [m]", 1.0),
    ("rpe_rot", "RPE rot [deg]", 1.0),
    ("ate_online", "ATE online [m]", 1.0),
)
MAP_METRICS = (
    ("map_precision", "map precision", 1.0),
    ("map_recall", "map recall", 1.0),
    ("map_doubled_walls", "doubled walls", 1.0),
)
FIGURES = (
    ("peak_rss_bytes", "peak memory [MB]", 1e-6),
    ("elapsed_s", "time [s]", 1.0),
    ("cpu_wait_share", "CPU wait share", 1.0),
    ("frames", "frames", 1.0),
)
ERROR_SHOWN = 120  # characters of a failed run's error in its row


@dataclass
class Link:
    text: str
    href: str  # relative to the study folder, where report.md and report.html are


@dataclass
class RunRow:
    key: str
    status: str  # "ok", or "error: ..." shortened
    ok: bool
    cells: list[str]  # one per heading after the run's identity
    identity: list[str]  # route, [camera], noise, method, seed
    links: list[Link]
    anchor: str | None = None  # the first row of a (route, camera, noise, method) group has one


@dataclass
class RunsTable:
    title: str
    caption: str
    identity: list[str]  # headings of the run's identity columns
    headings: list[str]  # headings of the value columns
    rows: list[RunRow] = field(default_factory=list)


def _in_study(out: Path, path: str | None) -> str | None:
    """A path the database holds (relative to the study folder, or absolute inside it) as a link
    relative to the study folder, if the file is there."""
    if not path:
        return None
    candidate = Path(path)
    if candidate.is_absolute():
        try:
            candidate = candidate.relative_to(out.absolute())
        except ValueError:
            return None
    return candidate.as_posix() if (out / candidate).is_file() else None


def log_link(out: Path, run: dict[str, Any]) -> str | None:
    """The run's log, relative to the study folder, only if it holds anything: studies made before
    the logs had an opening line left empty ones."""
    for path in (run.get("log_path"), f"logs/{run['key']}.log"):
        shown = _in_study(out, path)
        if shown and (out / shown).stat().st_size > 0:
            return shown
    return None


def _links(out: Path, run: dict[str, Any]) -> list[Link]:
    links = []
    run_dir = run.get("run_dir")
    for text, path in (
        ("trajectory", run.get("trajectory_path") or (run_dir and f"{run_dir}/{TRAJECTORY}")),
        ("stats", run.get("stats_path") or (run_dir and f"{run_dir}/{STATS}")),
        ("config", run_dir and f"{run_dir}/{CONFIG}"),
    ):
        shown = _in_study(out, path)
        if shown:
            links.append(Link(text, shown))
    # What native code (ORB-SLAM3's C++) printed during the run is in the run folder's console.log.
    console = _in_study(out, run_dir and f"{run_dir}/{CONSOLE_LOG}")
    if console and (out / console).stat().st_size > 0:
        links.append(Link("console", console))
    log = log_link(out, run)
    if log:
        links.append(Link("log", log))
    return links


def _value(run: dict[str, Any], column: str, scale: float) -> str:
    value = run.get(column)
    if value is None:
        return "–"
    if column == "frames":
        return str(int(value))
    return format_number(scale * float(value))


def _order(results: StudyResults):
    """Runs in the study's order: route, camera, noise, method as the study names them, then seed."""

    def index(values: list[str], value: str) -> int:
        return values.index(value) if value in values else len(values)

    return lambda r: (
        index(results.routes, r["route"]),
        index(results.cameras, r.get("camera_name", "")),
        index(results.sensors, r.get("sensor") or "ideal"),
        index(results.perturbations, r.get("perturbation") or "none"),
        index(results.noise, r["noise"]),
        index(results.methods, r["method"]),
        r["seed"],
        r.get("repeat") or 0,
    )


def every_run_table(results: StudyResults) -> RunsTable:
    out = results.out
    with_maps = any(r.get("map_precision") is not None for r in results.ok)
    columns = METRICS + (MAP_METRICS if with_maps else ()) + FIGURES
    repeats = any(r.get("repeat") for r in results.runs)
    identity = (
        ["route"]
        + (["camera"] if results.by_camera else [])
        + (["sensor"] if results.by_sensor else [])
        + (["perturbation"] if results.by_perturbation else [])
        + ["noise", "method", "seed"]
        + (["repeat"] if repeats else [])
    )
    table = RunsTable(
        "All runs",
        "Every recorded run, one row each: its metrics (ATE, E_trans and E_rot as in Table 1, APE and RPE as "
        "in Table 1b, the ATE of the online trajectory), peak memory (MB, as in Table 2), the time of its "
        "process from start to end, its CPU wait share (how long its threads were ready but waited for a core, "
        f"over that wait plus their CPU time; 'starved' above {STARVED_SHARE:g}), and links to the files of its "
        "folder (final trajectory, stats.json, "
        "config.toml, and console.log: what native code such as ORB-SLAM3 printed) and to its log when the log "
        "holds anything. A cell of Tables 1 to 3 links to its rows.",
        identity,
        ["status"] + [heading for _, heading, _ in columns] + ["files"],
    )
    seen: set[str] = set()
    for run in sorted(results.runs, key=_order(results)):
        group = results.group_of(run)
        anchor = runs_anchor(run["route"], run["noise"], run["method"], group)
        ok = run["status"] == "ok"
        error = (run.get("error") or "").splitlines()[0] if not ok and run.get("error") else ""
        status = "ok" if ok else f"{run['status']}: {error[:ERROR_SHOWN]}" + ("…" if len(error) > ERROR_SHOWN else "")
        if ok and starved(run.get("cpu_wait_share")):
            status = "ok, starved"
        table.rows.append(
            RunRow(
                key=run["key"],
                status=status,
                ok=ok,
                identity=(
                    [run["route"]]
                    + ([group.camera or ""] if results.by_camera and group is not None else [])
                    + ([group.sensor or ""] if results.by_sensor and group is not None else [])
                    + ([group.perturbation or ""] if results.by_perturbation and group is not None else [])
                    + [run["noise"], run["method"], str(run["seed"])]
                    + ([str(run.get("repeat") or 0)] if repeats else [])
                ),
                cells=[_value(run, column, scale) for column, _, scale in columns],
                links=_links(out, run),
                anchor=None if anchor in seen else anchor,
            )
        )
        seen.add(anchor)
    return table


def _md_escape(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def runs_markdown(table: RunsTable) -> str:
    header = table.identity + table.headings
    lines = [f"### {table.title}", "", table.caption, "", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for row in table.rows:
        files = " ".join(f"[{link.text}]({link.href})" for link in row.links) or "–"
        lines.append("| " + " | ".join(_md_escape(c) for c in row.identity + [row.status] + row.cells + [files]) + " |")
    return "\n".join(lines) + "\n"


def runs_html(table: RunsTable) -> str:
    import html

    esc = html.escape
    parts = [
        f'<h3 id="all-runs">{esc(table.title)}</h3><p class="caption">{esc(table.caption)}</p>'
        f'<table class="results runs" data-title="{esc(table.title)}"><thead><tr>'
        + "".join(f"<th>{esc(h)}</th>" for h in table.identity + table.headings)
        + "</tr></thead><tbody>"
    ]
    for row in table.rows:
        anchor = f' id="{esc(row.anchor)}"' if row.anchor else ""
        status = "ok" if row.ok else "failed"
        cells = "".join(f'<td class="id">{esc(c)}</td>' for c in row.identity)
        cells += f'<td class="status {status}">{esc(row.status)}</td>'
        cells += "".join(f"<td>{esc(c)}</td>" for c in row.cells)
        cells += (
            '<td class="files">'
            + " ".join(f'<a href="{esc(link.href)}">{esc(link.text)}</a>' for link in row.links)
            + "</td>"
        )
        parts.append(f'<tr{anchor} data-key="{esc(row.key)}">{cells}</tr>')
    parts.append("</tbody></table>")
    return "".join(parts)
