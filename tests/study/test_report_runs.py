"""The report to drill into, without running a study: the table of every run and its links, n
beside every mean ± std at one precision, APE/RPE, memory in MB, plotly inline once."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from longslam.study.record import RunRecord
from longslam.study.report import StudyResults, accuracy_table, format_mean_std, memory_table
from longslam.study.report.figures import Figure
from longslam.study.report.render import Report, render_html, render_markdown, table_html
from longslam.study.report.runs import every_run_table, runs_html, runs_markdown
from longslam.study.report.tables import field_table, paper_tables
from longslam.study.run_log import closing_line, opening_line


def test_mean_and_std_show_n_and_share_their_decimal_place():
    assert format_mean_std([1.0] * 5) == "1.00 ± 0.00 (n=5)"  # was '1.00 ± 0'
    assert format_mean_std([0.00933, 0.00943, 0.00953]) == "0.00943 ± 0.00010 (n=3)"  # was '0.00943 ± 0.0001'
    assert format_mean_std([0.1, 0.3]) == "0.200 ± 0.141 (n=2)"
    assert format_mean_std([1234.0, 1300.0]) == "1267 ± 47 (n=2)"
    assert format_mean_std([0.25]) == "0.250 (n=1)" and format_mean_std([]) == "–"
    # The two numbers of a cell always have as many decimals as each other.
    for values in ([0.0123, 0.0456], [5.0, 5.2, 5.1], [123.0, 140.0], [0.0, 0.0, 0.3]):
        mean, std = re.match(r"(\S+) ± (\S+) \(n=\d+\)", format_mean_std(values)).groups()
        assert len(mean.partition(".")[2]) == len(std.partition(".")[2]), values


def _run(seed: int, method: str = "odometry", status: str = "ok", **more) -> dict:
    key = f"paper-300m/small/{method}/seed-{seed}"
    run = {"key": key, "method": method, "route": "paper-300m", "noise": "small", "seed": seed, "status": status,
           "camera_name": "camera", "error": None, "run_dir": f"runs/{key}", "log_path": None,
           "trajectory_path": f"runs/{key}/trajectory.txt", "stats_path": f"runs/{key}/stats.json",
           "elapsed_s": 12.5, "frames": 2113}
    values = dict(ate=0.1 + 0.2 * seed, e_trans=0.01, e_rot=0.02, ape_rmse=0.12 + 0.2 * seed, rpe_trans=0.005,
                  rpe_rot=0.04, ate_online=0.2, peak_rss_bytes=2.0e8 + 2e6 * seed)
    if status != "ok":
        values = {k: None for k in values}
        run.update(run_dir=None, trajectory_path=None, stats_path=None)
    run.update(values)
    run.update(more)
    return run


def _results(out: Path, runs: list[dict], methods: list[str] | None = None) -> StudyResults:
    ok = [r for r in runs if r["status"] == "ok"]
    methods = methods or list(dict.fromkeys(r["method"] for r in runs))
    return StudyResults(out, {"align": "none"}, runs, ok, ["paper-300m"], ["small"], methods)


def test_the_field_metrics_have_a_table_and_memory_is_in_mb_read_inside_the_run():
    runs = [_run(0), _run(1)]
    results = _results(Path("."), runs)
    field = field_table(results)
    assert [label for _, label in field.row_labels] == ["APE RMSE [m]", "RPE trans RMSE [m]", "RPE rot RMSE [deg]"]
    assert field.rows[0][0].text == "0.220 ± 0.141 (n=2)"  # the paper has no APE or RPE: no paper rows
    memory = memory_table(results)
    assert [row[0].text for row in memory.rows] == ["201 ± 1 (n=2)", "3600", "520"]  # MB; the paper's 3.6 and 0.52 GB
    assert "(MB" in memory.caption and "VmHWM" in memory.caption and "inside that process" in memory.caption
    assert "outside" not in memory.caption
    accuracy = accuracy_table(results)
    assert accuracy.rows[2][0].text == "0.200 ± 0.141 (n=2)"  # ATE
    published = paper_tables()[1]  # the appendix of a study off the paper's routes: MB too
    assert [c.text for c in published.rows[0]][:2] == ["3600", "3500"] and "in MB" in published.caption


def _files(out: Path, run: dict, log: str | None) -> None:
    folder = out / run["run_dir"]
    folder.mkdir(parents=True)
    for name in ("trajectory.txt", "stats.json", "config.toml"):
        (folder / name).write_text("x\n")
    if log is not None:
        path = out / "logs" / f"{run['key']}.log"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(log)
        run["log_path"] = str(path.absolute())  # the database holds the absolute path


def test_every_run_has_a_row_with_its_metrics_memory_time_status_and_links(tmp_path):
    good, quiet = _run(0), _run(1)
    _files(tmp_path, good, "longslam study run ...\nfinished ok\n")
    _files(tmp_path, quiet, "")  # a study made before the logs had their lines: an empty log
    (tmp_path / good["run_dir"] / "console.log").write_text("ORB-SLAM3 ... Loading ORB Vocabulary\n")
    (tmp_path / quiet["run_dir"] / "console.log").write_text("")
    failed = _run(0, "crashy", "error", error="RuntimeError: crashy fails on purpose at frame 5\nmore text")
    traceback = tmp_path / "logs" / "paper-300m/small/crashy/seed-0.log"  # log_path: none recorded
    traceback.parent.mkdir(parents=True, exist_ok=True)
    traceback.write_text("Traceback ...\nRuntimeError: crashy fails on purpose at frame 5\n")
    results = _results(tmp_path, [failed, quiet, good], ["odometry", "crashy"])
    table = every_run_table(results)
    assert [row.key for row in table.rows] == [good["key"], quiet["key"], failed["key"]]  # the study's order
    assert table.identity == ["route", "noise", "method", "seed"]
    headings = table.headings
    assert headings[:8] == ["status", "ATE [m]", "E_trans", "E_rot [deg/m]", "APE RMSE [m]", "RPE trans [m]",
                            "RPE rot [deg]", "ATE online [m]"]
    assert "peak memory [MB]" in headings and "time [s]" in headings and headings[-1] == "files"
    first = dict(zip(headings[1:], table.rows[0].cells))
    assert first["ATE [m]"] == "0.100" and first["peak memory [MB]"] == "200" and first["time [s]"] == "12.5"
    links = {row.key: [(link.text, link.href) for link in row.links] for row in table.rows}
    folder = f"runs/{good['key']}"
    assert links[good["key"]] == [("trajectory", f"{folder}/trajectory.txt"), ("stats", f"{folder}/stats.json"),
                                  ("config", f"{folder}/config.toml"), ("console", f"{folder}/console.log"),
                                  ("log", f"logs/{good['key']}.log")]
    assert [text for text, _ in links[quiet["key"]]] == ["trajectory", "stats", "config"]  # its logs are empty
    assert links[failed["key"]] == [("log", f"logs/{failed['key']}.log")]
    assert table.rows[2].status == "error: RuntimeError: crashy fails on purpose at frame 5" and not table.rows[2].ok
    for href in (h for row in links.values() for _, h in row):
        assert (tmp_path / href).is_file() and not Path(href).is_absolute()

    markdown, page = runs_markdown(table), runs_html(table)
    assert markdown.count("\n| paper-300m |") == 3 and f"[log](logs/{good['key']}.log)" in markdown
    assert page.count("<tr ") == 3 and f'<a href="{folder}/trajectory.txt">trajectory</a>' in page
    # A cell of Table 1 links to the first row of its runs.
    table1 = table_html(accuracy_table(results))
    targets = set(re.findall(r'href="#([^"]+)"', table1))
    ids = set(re.findall(r' id="([^"]+)"', page))
    assert targets and targets <= ids and "runs/paper-300m/small/odometry" in ids


def test_the_page_has_plotly_inline_once_and_works_offline(tmp_path):
    import plotly.graph_objects as go

    png = tmp_path / "a.png"
    png.write_bytes(b"\x89PNG\r\n\x1a\n")
    figures = [Figure(Path("a.png"), "static"),
               Figure(Path("a.png"), "one", go.Figure(go.Scatter(x=[0, 1], y=[1, 0]))),
               Figure(Path("a.png"), "two", go.Figure(go.Scatter(x=[0, 1], y=[0, 1])))]
    report = Report("longslam study report: t", [], [], figures, [], [], [], None)
    page = render_html(report, tmp_path)
    assert page.count("window.Plotly = Plotly") == 1  # plotly.js itself, once
    assert page.count('class="plotly-graph-div"') == 2 and page.count("<img src=") == 1
    assert not re.search(r'<script[^>]+src=', page)  # nothing fetched: the page works offline
    markdown = render_markdown(report)
    assert markdown.count("![") == 3 and "plotly" not in markdown.lower()  # report.md keeps the PNGs


def test_a_runs_log_opens_with_what_ran_and_closes_with_how_it_ended():
    class Spec:
        key, method_name, params, route, noise, seed = "r/small/keyframe/seed-2", "keyframe", {"grid_cell": 0.1}, "r", "small", 2

    line = opening_line(Spec())
    assert line.startswith("longslam study run r/small/keyframe/seed-2: method keyframe (grid_cell=0.1)")
    assert "seed 2" in line and "process " in line
    ok = RunRecord("ok", metrics={"ate": 0.0123}, measurements={"frames": 55, "peak_rss_bytes": 2.5e8, "method_time_s": 3.0})
    assert closing_line(ok, 4.0) == "finished ok after 4.0 s: 55 frames, ATE 0.0123 m, peak RSS 250 MB, method time 3.0 s"
    assert closing_line(RunRecord.failed("RuntimeError: no"), 1.0) == "failed after 1.0 s: RuntimeError: no"


@pytest.mark.parametrize("values", [[0.5, 0.5000001], list(np.linspace(0.01, 0.02, 7))])
def test_precision_is_the_means(values):
    mean, std = format_mean_std(values).split(" (")[0].split(" ± ")
    assert len(mean.replace("-", "").replace(".", "").lstrip("0")) == 3  # three significant digits


def test_the_interactive_trajectories_have_every_seed_and_a_menu_for_one():
    from longslam.core.gridmap import FREE, GridMap
    from longslam.study.report.interactive import curves_figure, trajectories_figure

    grid = GridMap(np.full((40, 60), FREE, dtype=np.int8), 0.1, (0.0, 0.0))
    line = np.column_stack([np.linspace(0.5, 5.5, 50), np.full(50, 2.0)])
    estimates = {m: {s: line + 0.01 * s for s in (0, 1, 2)} for m in ("keyframe", "submap")}
    ates = {(m, s): 0.01 * s for m in estimates for s in (0, 1, 2)}
    fig = trajectories_figure(grid, (0, 6, 0, 4), line, estimates, ates, np.array([[0.5, 2], [5.5, 2], [0.5, 2.1]]))
    names = [trace.name for trace in fig.data]
    for method in estimates:
        for seed in (0, 1, 2):
            assert f"{method}, seed {seed} (ATE {0.01 * seed:.3f} m)" in names
    assert names[:2] == ["floor plan", "ground truth"] and names[-2:] == ["waypoints", "start"]  # places over the lines
    assert list(fig.data[-2].text) == ["0, 2", "1"]
    menu = {b.label: b.args[0]["visible"] for b in fig.layout.updatemenus[0].buttons}
    assert list(menu) == ["all seeds", "seed 0", "seed 1", "seed 2"] and all(menu["all seeds"])
    shown = [name for name, visible in zip(names, menu["seed 1"]) if visible]
    assert shown == ["floor plan", "ground truth", "keyframe, seed 1 (ATE 0.010 m)", "submap, seed 1 (ATE 0.010 m)",
                     "waypoints", "start"]
    assert fig.layout.xaxis.title.text == "x [m]" and fig.layout.yaxis.title.text == "y [m]"
    widths = {t.legendgroup: t.line.width for t in fig.data if t.legendgroup}
    assert widths["keyframe"] > widths["submap"]  # the one drawn first, under, is wider

    curve = np.column_stack([np.linspace(0, 8, 20), np.linspace(0, 0.1, 20)])
    curves = curves_figure({"noise large": {"keyframe": {0: curve, 1: curve * 1.1}}, "noise small": {"keyframe": {0: curve}}},
                           "position error [m]")
    assert len(curves.data) == 3 and sum(bool(t.showlegend) for t in curves.data) == 1  # a line per run, one legend entry


def test_a_starved_run_is_marked_and_a_repeated_cell_is_a_distribution():
    from longslam.study.report.distribution import FAILURE_RULE, distribution_table

    odometry = [_run(0, "odometry", method_name="odometry")]
    odometry[0]["ate"] = 2.0
    stats = lambda **s: {"measurements": {"method_stats": s}}  # noqa: E731
    system = [
        _run(0, "system", method_name="system", repeat=0, cpu_wait_share=0.01, **stats(maps=1)),
        _run(0, "system", method_name="system", repeat=1, cpu_wait_share=0.35, **stats(maps=2)),  # a new map
        _run(0, "system", method_name="system", repeat=2, cpu_wait_share=0.02,
             **stats(maps=1, tracking_lost_longest_s=3.2)),
        _run(0, "system", method_name="system", repeat=3, cpu_wait_share=0.0, **stats(maps=1)),
        _run(0, "system", "error", method_name="system", repeat=4),
    ]
    for run, ate in zip(system, (0.06, 11.6, 0.09, 2.5)):
        run["ate"] = ate  # the last: worse than dead reckoning's 2.0
    runs = odometry + system
    results = _results(Path("."), runs)
    results.config["repeats"] = 5
    table = every_run_table(results)
    assert table.identity[-1] == "repeat"
    assert [row.status for row in table.rows if row.key.endswith("seed-0") and "system" in row.key][:2] == ["ok", "ok, starved"]
    assert "CPU wait share" in table.headings
    spread = distribution_table(results)
    row = spread.row_labels.index(("system", ""))
    cells = {heading: cell.text for (_, heading), cell in zip(spread.columns, spread.rows[row])}
    assert cells["runs"] == "5" and cells["ATE median [m]"] == "1.29"  # of 0.06, 0.09, 2.5 and 11.6
    assert cells["ATE min-max [m]"] == "0.0600-11.6"
    assert cells["failed"].startswith("4 / 5") and "new map" in cells["failed"] and "tracking lost" in cells["failed"]
    assert "worse than dead reckoning" in cells["failed"] and "error" in cells["failed"]
    assert cells["starved"] == "1 / 5"
    assert "more than 2 s" in FAILURE_RULE
