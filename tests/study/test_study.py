"""Studies end to end on a tiny route with a tiny camera: the database, crashes, the report,
killing and resuming, the Ray executor and the report in a real browser."""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from helpers.studies import chromium, write_study
from longslam.cli.main import main
from longslam.study.config import load_study
from longslam.study.database import DB_NAME
from longslam.study.report import Cell, StudyResults, accuracy_table, format_mean_std, memory_table
from longslam.study.driver import run_study

pytestmark = pytest.mark.slow  # runs studies, some in processes



def _rows(out: Path) -> list[dict]:
    with sqlite3.connect(out / DB_NAME) as conn:
        conn.row_factory = sqlite3.Row
        return [dict(r) for r in conn.execute("SELECT * FROM runs")]


def test_a_study_writes_one_row_per_run_and_records_crashes(study):
    out, summary = study
    assert (summary.planned, summary.skipped, summary.ran, summary.failed) == (8, 0, 8, 4)
    rows = {r["key"]: r for r in _rows(out)}
    assert len(rows) == 8
    for seed in (0, 1):
        ok = rows[f"tiny/large/odometry/seed-{seed}"]
        assert ok["status"] == "ok" and ok["error"] is None
        assert 0 < ok["ate"] < 1 and 0 < ok["e_trans"] < 0.2 and ok["peak_rss_bytes"] > 50e6
        assert ok["frames"] > 40 and ok["elapsed_s"] > 0 and ok["config_hash"]
        assert json.loads(ok["params"]) == {} and json.loads(ok["camera"])["width"] == 64
        assert (out / ok["trajectory_path"]).is_file() and (out / ok["stats_path"]).is_file()
        assert ok["grid_path"] is None and ok["map_precision"] is None  # no grid: no map quality
        error_curve, memory_curve = json.loads(ok["error_curve"]), json.loads(ok["memory_curve"])
        assert error_curve[0] == [0.0, pytest.approx(0.0, abs=1e-6)] and 7.5 < error_curve[-1][0] < 8.5
        assert memory_curve[0][0] == 0.0 and memory_curve[-1][0] > 7.5 and memory_curve[-1][1] > 50e6

        gridded = rows[f"tiny/large/gridded/seed-{seed}"]
        assert gridded["status"] == "ok" and (out / gridded["grid_path"]).is_file()
        assert 0.8 < gridded["map_precision"] <= 1.0 and 0.3 < gridded["map_recall"] <= 1.0
        # The best planar alignment never scores below the map as it is; the dead-reckoned map
        # of a short route has no doubled wall.
        assert gridded["map_precision_aligned"] >= gridded["map_precision"] - 1e-9
        assert gridded["map_recall_aligned"] is not None and gridded["map_doubled_walls"] is not None

        crashed = rows[f"tiny/large/crashy/seed-{seed}"]
        assert crashed["status"] == "error" and "crashy fails on purpose at frame 5" in crashed["error"]
        assert "RuntimeError" in crashed["traceback"] and crashed["ate"] is None
        died = rows[f"tiny/large/dies/seed-{seed}"]
        assert died["status"] == "error" and "SIGKILL" in died["error"]
        console = out / "logs" / f"tiny/large/dies/seed-{seed}.console.log"
        assert str(console) in died["error"] and "assertion failed, about to die" in console.read_text()
    assert not list((out / "runs").rglob(".*partial*"))


def test_the_report_has_both_tables_and_the_papers_numbers(study):
    out, _ = study
    markdown = (out / "report.md").read_text()
    page = (out / "report.html").read_text()
    for text in (markdown, page):
        assert "Table 1: accuracy" in text and "Table 2: peak memory" in text and "Table 3: map quality" in text
        assert "Muravyev" in text and "RTAB-Map" in text and "Voxgraph" in text
        assert "0.017 ± 0.002" in text and "8600" in text  # the paper's numbers, Tables 1 and 2 (8.6 GB in MB)
        assert "crashy fails on purpose" in text
    table1 = markdown.split("### Table 1")[1].split("###")[0]
    assert re.search(r"\| odometry \| E_trans \| \*\*[0-9.]+ ± [0-9.]+ \(n=2\)\*\* \|", table1)
    assert "precision, aligned" in markdown and "doubled walls" in markdown
    for name in ("trajectories-tiny-large", "ate-tiny", "memory-tiny", "maps-tiny-large", "map-tiny-large-gridded"):
        assert (out / "report_files" / f"{name}.png").is_file() and f"report_files/{name}.png" in markdown
    # The trajectories and the two curves are plotly figures on the page; the two maps are images.
    assert page.count('<img src="data:image/png;base64,') == 2 and "report_files/" not in page
    assert page.count('class="plotly-graph-div"') == 3
    # `longslam report` writes it again from the database alone.
    (out / "report.html").unlink()
    assert main(["report", str(out)]) == 0
    assert (out / "report.html").is_file()


def test_the_papers_numbers_stand_beside_ours_on_the_papers_routes():
    runs = [
        {"method": "odometry", "route": "paper-300m", "noise": "small", "seed": s, "status": "ok",
         "ate": 0.1 + 0.2 * s, "e_trans": 0.01, "e_rot": 0.02, "peak_rss_bytes": 2e8}
        for s in range(2)
    ]
    results = StudyResults(Path("."), {}, runs, runs, ["paper-300m"], ["small"], ["odometry"])
    table = accuracy_table(results)
    labels = [f"{m} {k}" for m, k in table.row_labels]
    assert labels[:3] == ["odometry E_trans", "odometry E_rot [deg/m]", "odometry ATE [m]"]
    assert "RTAB-Map (paper) ATE [m]" in labels and "Voxgraph (paper) E_trans" in labels
    cells = dict(zip(labels, (row[0] for row in table.rows)))
    assert cells["odometry ATE [m]"].text == "0.200 ± 0.141 (n=2)" and cells["odometry ATE [m]"].best
    assert cells["RTAB-Map (paper) ATE [m]"].text == "0.99 ± 0.087" and not cells["RTAB-Map (paper) ATE [m]"].best
    assert cells["odometry E_trans"].best and not cells["Voxgraph (paper) E_trans"].best
    memory = memory_table(results)
    assert [row[0].text for row in memory.rows] == ["200 ± 0 (n=2)", "3600", "520"]  # MB
    assert isinstance(memory.rows[0][0], Cell) and memory.rows[0][0].best
    assert format_mean_std([]) == "–" and format_mean_std([0.25]) == "0.250 (n=1)"


def test_a_killed_study_resumes_and_runs_everything_exactly_once(env):
    file = write_study(env, "resume", ["odometry"], ["none", "large"], [0, 1])
    out = env / "resume-out"
    command = [sys.executable, "-m", "longslam", "study", str(file), "--out", str(out), "--jobs", "1", "--no-report"]
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 90
    landed = 0
    while time.monotonic() < deadline and process.poll() is None:
        if (out / DB_NAME).is_file():
            try:
                landed = len(_rows(out))
            except sqlite3.OperationalError:  # the table is not created yet
                landed = 0
            if landed:
                break
        time.sleep(0.05)
    assert landed >= 1, process.stderr.read().decode() if process.poll() is not None else "no run landed in time"
    process.send_signal(signal.SIGKILL)
    process.wait()
    before = {r["key"]: r["finished_at"] for r in _rows(out)}
    assert 1 <= len(before) < 4, "the study was not killed part-way"

    summary = run_study(load_study(file), out, jobs=2, report=False, progress=False)
    assert (summary.planned, summary.skipped, summary.ran, summary.failed) == (4, len(before), 4 - len(before), 0)
    rows = _rows(out)
    assert sorted(r["key"] for r in rows) == sorted(
        f"tiny/{n}/odometry/seed-{s}" for n in ("none", "large") for s in (0, 1)
    )
    assert all(r["status"] == "ok" for r in rows)
    assert {k: r["finished_at"] for r in rows for k in [r["key"]] if k in before} == before  # not run again
    assert not list((out / "runs").rglob(".*partial*"))
    with sqlite3.connect(out / DB_NAME) as conn:
        assert conn.execute("SELECT COUNT(*), COUNT(DISTINCT key) FROM runs").fetchone() == (4, 4)
    # Started again with nothing left to do, it does nothing.
    again = run_study(load_study(file), out, report=False, progress=False)
    assert (again.skipped, again.ran) == (4, 0)


def test_a_second_study_into_a_busy_folder_stops_with_a_clear_message(study, env, capsys):
    from longslam.study.lock import study_lock

    out, _ = study
    before = _rows(out)
    file = write_study(env, "main", ["odometry", "gridded", "crashy", "dies"], ["large"], [0, 1])
    with study_lock(out):  # another study holds the folder
        assert main(["study", str(file), "--out", str(out), "--retry-failed", "--no-report"]) == 2
    err = capsys.readouterr().err
    assert "in use by another study" in err and str(os.getpid()) in err and "Traceback" not in err
    assert _rows(out) == before  # nothing recorded again, nothing overwritten


def test_a_study_that_fails_validation_leaves_nothing_behind(study, env, tmp_path, capsys):
    (env / "walled.txt").write_text("20 31.25\n-40 -40\n")  # the second waypoint is outside the building
    file = env / "walled.toml"
    file.write_text('name = "walled"\nroutes = ["walled.txt"]\nnoise = ["none"]\nmethods = ["odometry"]\nseeds = 1\n')
    fresh = tmp_path / "fresh"
    assert main(["study", str(file), "--out", str(fresh)]) == 2
    assert "walled" in capsys.readouterr().err
    assert not fresh.exists()
    # Into an existing study folder: its stored config and its files stay as they were.
    out, _ = study
    with sqlite3.connect(out / DB_NAME) as conn:
        config = conn.execute("SELECT value FROM study WHERE key = 'config'").fetchone()
    listing = sorted(p.relative_to(out) for p in out.rglob("*"))
    assert main(["study", str(file), "--out", str(out)]) == 2
    with sqlite3.connect(out / DB_NAME) as conn:
        assert conn.execute("SELECT value FROM study WHERE key = 'config'").fetchone() == config
    assert sorted(p.relative_to(out) for p in out.rglob("*")) == listing


def test_ray_executor_against_a_local_ray(env):
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        config = load_study(write_study(env, "ray", ["odometry"], ["large"], [0, 1]))
        out = env / "ray-out"
        summary = run_study(config, out, executor="ray", progress=False, report=False)
    finally:
        ray.shutdown()
    assert (summary.ran, summary.failed) == (2, 0)
    rows = _rows(out)
    assert len(rows) == 2 and all(r["status"] == "ok" and r["executor"] == "ray" for r in rows)
    for row in rows:
        assert (out / row["trajectory_path"]).is_file() and row["ate"] > 0 and row["peak_rss_bytes"] > 0


CHECK = """<script>
window.addEventListener("load", () => {
  const images = Array.from(document.images);
  const loaded = images.filter((img) => img.complete && img.naturalWidth > 0).length;
  const tables = Array.from(document.querySelectorAll("table.results")).map(
    (t) => ({title: t.dataset.title, rows: t.querySelectorAll("tbody tr").length, height: t.offsetHeight}));
  const plots = Array.from(document.querySelectorAll(".js-plotly-plot"));
  const drawn = plots.filter((p) => p.querySelector("svg.main-svg") && p.querySelectorAll("path.js-line").length > 0);
  const runs = document.querySelector("table.runs");
  const cells = Array.from(document.querySelectorAll("table.results a.cell"));
  const landed = cells.filter((a) => document.getElementById(decodeURIComponent(a.getAttribute("href").slice(1))));
  const marker = document.createElement("pre");
  marker.id = "check";
  marker.textContent = JSON.stringify({images: images.length, loaded: loaded, tables: tables, plots: plots.length,
    drawn: drawn.length, menus: document.querySelectorAll(".updatemenu-container").length,
    runs: runs ? runs.querySelectorAll("tbody tr").length : 0, runLinks: runs ? runs.querySelectorAll("a").length : 0,
    cells: cells.length, landed: landed.length});
  document.body.appendChild(marker);
});
</script></body>"""


@pytest.mark.skipif(chromium() is None, reason="chromium is not installed (apt-get install chromium)")
def test_report_page_in_a_headless_browser(study, tmp_path):
    out, _ = study
    page = tmp_path / "report.html"
    page.write_text((out / "report.html").read_text().replace("</body>", CHECK))
    command = [
        chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run", f"--user-data-dir={tmp_path / 'profile'}",
        "--virtual-time-budget=10000", "--dump-dom", page.as_uri(),
    ]
    dom = subprocess.run(command, capture_output=True, text=True, timeout=120).stdout
    found = re.search(r'<pre id="check">(.*?)</pre>', dom)
    assert found, f"the page did not load: {dom[:500]}"
    check = json.loads(found.group(1).replace("&quot;", '"'))
    assert check["images"] == 2 and check["loaded"] == 2  # every map figure decoded and shown
    # The trajectories (with a seed menu) and the two curves, drawn by the inline plotly.js.
    assert check["plots"] == 3 and check["drawn"] == 3 and check["menus"] >= 1
    titles = [t["title"] for t in check["tables"]]
    assert titles[:4] == ["Table 1: accuracy", "Table 1b: APE and RPE", "Table 2: peak memory", "Table 3: map quality"]
    assert "All runs" in titles and check["runs"] == 8  # every run has its row
    assert check["runLinks"] == 4 * 4 + 4  # the good runs' trajectory, stats, config and log; the failed runs' logs
    assert check["cells"] > 0 and check["landed"] == check["cells"]  # each cell's link lands on its runs' row
    assert "The paper's Table 1 as published" in titles and "The paper's Table 2 as published" in titles
    for table in check["tables"]:
        assert table["rows"] >= 2 and table["height"] > 20, table  # laid out on the page


def _cameras_study(root: Path, name: str, cameras: dict[str, tuple[int, int]], methods: list[str]) -> Path:
    tables = "".join(f"[cameras.{camera}]\nwidth = {w}\nheight = {h}\n" for camera, (w, h) in cameras.items())
    path = root / f"{name}.toml"
    path.write_text(f'name = "{name}"\nroutes = ["tiny.txt"]\nnoise = ["large"]\nmethods = {json.dumps(methods)}\nseeds = [0]\n' + tables)
    return path


def test_a_study_with_two_cameras_runs_each_records_both_and_resumes(env):
    cameras = {"small": (64, 48), "wide": (80, 60)}
    file = _cameras_study(env, "cameras", cameras, ["odometry", "gridded"])
    out = env / "cameras-out"
    summary = run_study(load_study(file), out, jobs=2, progress=False)
    assert (summary.planned, summary.skipped, summary.ran, summary.failed) == (4, 0, 4, 0)
    rows = {r["key"]: r for r in _rows(out)}
    assert set(rows) == {f"tiny/{c}/large/{m}/seed-0" for c in cameras for m in ("odometry", "gridded")}
    for camera, (width, height) in cameras.items():
        for method in ("odometry", "gridded"):
            row = rows[f"tiny/{camera}/large/{method}/seed-0"]
            assert row["status"] == "ok" and row["camera_name"] == camera and row["route"] == "tiny"
            assert (json.loads(row["camera"])["width"], json.loads(row["camera"])["height"]) == (width, height)
            assert row["run_dir"] == f"runs/tiny/{camera}/large/{method}/seed-0"
            assert (out / row["trajectory_path"]).is_file() and 0 < row["ate"] < 1
            assert json.loads((out / row["stats_path"]).read_text())["camera"] == camera
            assert (out / "logs" / "tiny" / camera / "large" / method / "seed-0.log").is_file()
        # Each camera's ground truth: the walls a camera sees depend on its field of view and range.
        assert (out / "routes" / "tiny" / camera / "observed.npy").is_file()
        assert (out / "routes" / "tiny" / camera / "groundtruth.txt").is_file()
    assert not (out / "routes" / "tiny" / "observed.npy").exists()
    # One sequence per camera, rendered at its resolution.
    sequences = {json.loads(r["measurements"])["sequence"] for r in rows.values()}
    assert len(sequences) == 2

    markdown = (out / "report.md").read_text()
    page = (out / "report.html").read_text()
    assert "Cameras: small: 64 x 48, 90.0 degree field of view, depth to 8.0 m; wide: 80 x 60" in markdown
    for title in ("Table 1", "Table 2", "Table 3", "Runs"):
        table = markdown.split(f"### {title}")[1].split("###")[0]
        assert "| method | camera |" in table, title
        for camera in cameras:
            assert re.search(rf"\| (odometry|gridded|) \| {camera} \|", table), (title, camera)
    table1 = markdown.split("### Table 1")[1].split("###")[0]
    assert re.search(r"\| odometry \| small \| E_trans \| (\*\*)?[0-9.]+ \(n=1\)(\*\*)? \|", table1)
    assert re.search(r"\|  \| wide \| E_trans \| (\*\*)?[0-9.]+ \(n=1\)(\*\*)? \|", table1)
    assert "<th>camera</th>" in page and 'rowspan="3" class="camera">wide</td>' in page
    for name in ("trajectories-tiny-small-large", "trajectories-tiny-wide-large", "ate-tiny-small", "ate-tiny-wide",
                 "memory-tiny-wide", "maps-tiny-small-large", "map-tiny-wide-large-gridded"):
        assert (out / "report_files" / f"{name}.png").is_file() and f"report_files/{name}.png" in markdown
    assert "route tiny, camera wide, noise large" in markdown

    # Again: nothing to do. With a third camera: only its runs.
    before = {k: r["finished_at"] for k, r in rows.items()}
    again = run_study(load_study(file), out, report=False, progress=False)
    assert (again.planned, again.skipped, again.ran) == (4, 4, 0)
    grown = _cameras_study(env, "cameras", {**cameras, "tall": (48, 64)}, ["odometry", "gridded"])
    more = run_study(load_study(grown), out, jobs=2, report=False, progress=False)
    assert (more.planned, more.skipped, more.ran, more.failed) == (6, 4, 2, 0)
    after = {r["key"]: r["finished_at"] for r in _rows(out)}
    assert {k: after[k] for k in before} == before and len(after) == 6


def test_an_old_one_camera_study_folder_reports_and_resumes(study, env, tmp_path):
    """A study folder from before cameras had names: its database has no camera_name column."""
    out, _ = study
    old = tmp_path / "old"
    shutil.copytree(out, old)
    with sqlite3.connect(old / DB_NAME) as conn:
        conn.execute("ALTER TABLE runs DROP COLUMN camera_name")
    (old / "report.md").unlink()
    assert main(["report", str(old)]) == 0
    markdown = (old / "report.md").read_text()
    assert "| method | metric |" in markdown and "| camera |" not in markdown
    assert "Camera 64 x 48, 90.0 degree field of view" in markdown
    assert (old / "report_files" / "trajectories-tiny-large.png").is_file()
    rows = _rows(old)  # the report opened the database, which now has the column
    assert "camera_name" in rows[0] and all(r["camera_name"] is None for r in rows)
    from longslam.study.database import ResultsDB

    with ResultsDB(old / DB_NAME) as db:
        assert {r["camera_name"] for r in db.runs()} == {"camera"}
    # The same study again resumes into the same rows: nothing is redone.
    file = write_study(env, "main", ["odometry", "gridded", "crashy", "dies"], ["large"], [0, 1])
    summary = run_study(load_study(file), old, report=False, progress=False)
    assert (summary.planned, summary.skipped, summary.ran) == (8, 8, 0)
    assert sorted(r["key"] for r in _rows(old)) == sorted(r["key"] for r in rows)


def test_a_camera_column_beside_the_papers_rows():
    from longslam.study.report.render import table_html, table_markdown

    runs = [
        {"method": "odometry", "route": "paper-300m", "noise": "small", "seed": s, "status": "ok", "camera_name": camera,
         "ate": ate + 0.01 * s, "e_trans": 0.01, "e_rot": 0.02, "peak_rss_bytes": 2e8}
        for s in range(2) for camera, ate in (("qvga", 0.5), ("vga", 0.2))
    ]
    config = {"cameras": {"qvga": {"width": 320}, "vga": {"width": 640}}}
    results = StudyResults(Path("."), config, runs, runs, ["paper-300m"], ["small"], ["odometry"], ["qvga", "vga"])
    table = accuracy_table(results)
    assert table.row_cameras == ["qvga"] * 3 + ["vga"] * 3 + [""] * 6  # the paper's rows have no camera
    ate = {camera: row[0] for camera, (_, metric), row in zip(table.row_cameras, table.row_labels, table.rows) if metric == "ATE [m]"}
    assert ate["qvga"].text == "0.505 ± 0.007 (n=2)" and ate["vga"].text == "0.205 ± 0.007 (n=2)" and ate["vga"].best
    markdown = table_markdown(table)
    assert "| method | camera | metric | paper-300m: small |" in markdown
    assert "| odometry | qvga | ATE [m] |" not in markdown and "|  | vga | E_trans |" in markdown
    assert "| RTAB-Map (paper) |  | E_trans | 0.017 ± 0.002 |" in markdown
    page = table_html(table)
    assert page.count('class="camera"') == 4 and '<th colspan="3"></th>' in page
    assert _row_widths(page) == [4] * len(table.rows)  # method, camera, metric, the one column
    # One camera: no camera column, as before cameras could be named.
    one = StudyResults(Path("."), {}, runs[:1], runs[:1], ["paper-300m"], ["small"], ["odometry"], ["qvga"])
    assert accuracy_table(one).row_cameras == [] and "| method | metric |" in table_markdown(accuracy_table(one))


def _row_widths(page: str) -> list[int]:
    """The width of each body row of an HTML table, counting the cells that rows above span into it."""
    widths, carried = [], []  # carried: rows still to cover, per spanning cell
    for row in re.findall(r"<tr>(.*?)</tr>", page.split("<tbody>")[1]):
        spans = [int(n or 1) for n in re.findall(r'<t[hd](?: rowspan="(\d+)")?[ >]', row)]
        widths.append(len(spans) + len(carried))
        carried = [n - 1 for n in carried + spans if n > 1]
    return widths


def _spans(rows: list[dict]) -> list[tuple[str, float, float]]:
    from datetime import datetime

    return [(r["method"], datetime.fromisoformat(r["started_at"]).timestamp(),
             datetime.fromisoformat(r["ended_at"]).timestamp()) for r in rows]


def _overlap(a: tuple[str, float, float], b: tuple[str, float, float]) -> bool:
    return a[1] < b[2] and b[1] < a[2]


def test_runs_of_one_core_share_the_machine(env):
    out = env / "sleepy-out"
    run_study(load_study(write_study(env, "sleepy", ["sleepy"], ["large"], [0, 1])), out, jobs=2, progress=False)
    spans = _spans(_rows(out))
    assert len(spans) == 2 and _overlap(*spans)  # the check below can fail


def test_a_run_that_needs_every_core_runs_alone_and_each_cell_repeats(env):
    path = write_study(env, "cores", ["sleepy", "hog"], ["large"], [0])
    path.write_text(path.read_text().replace('seeds = [0]', 'seeds = [0]\nrepeats = 3'))
    out = env / "cores-out"
    summary = run_study(load_study(path), out, jobs=2, progress=False)
    assert (summary.planned, summary.failed) == (6, 0)
    rows = _rows(out)
    assert sorted((r["method"], r["repeat"]) for r in rows) == [(m, k) for m in ("hog", "sleepy") for k in range(3)]
    assert {r["key"] for r in rows if r["method"] == "hog"} == {
        "tiny/large/hog/seed-0", "tiny/large/hog/seed-0-repeat-1", "tiny/large/hog/seed-0-repeat-2"}
    assert {r["method"]: r["cores"] for r in rows} == {"hog": 2, "sleepy": 1}
    assert all(r["cpu_wait_share"] is not None and 0.0 <= r["cpu_wait_share"] <= 1.0 for r in rows)
    spans = _spans(rows)
    for hog in (s for s in spans if s[0] == "hog"):
        assert not any(_overlap(hog, other) for other in spans if other is not hog)
    # Repeats of a cell are runs of their own, with their own folders.
    assert len({r["run_dir"] for r in rows}) == 6
    # A run recorded as starved of CPU is run again with --retry-starved, and only that run.
    starved = "tiny/large/sleepy/seed-0-repeat-1"
    first_start = {r["key"]: r for r in rows}[starved]["started_at"]
    with sqlite3.connect(out / DB_NAME) as conn:
        # The test decides which run starved: on a loaded machine the others may have waited too.
        conn.execute("UPDATE runs SET cpu_wait_share = CASE WHEN key = ? THEN 0.5 ELSE 0.0 END", (starved,))
    again = run_study(load_study(path), out, jobs=2, progress=False, retry_starved=True, report=False)
    assert (again.skipped, again.ran, again.failed) == (5, 1, 0)
    redone = {r["key"]: r for r in _rows(out)}[starved]
    assert redone["started_at"] > first_start  # run again, its wait measured afresh
    assert redone["cpu_wait_share"] != 0.5
