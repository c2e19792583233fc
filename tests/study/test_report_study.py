"""The report of a real (tiny) study to drill into: every run's log holds its output, the table of
every run links files that are there, every seed's trajectory is drawn, and in headless Chromium
the runs table and an interactive plotly figure show on a screenshot."""

from __future__ import annotations

import re
import subprocess

import numpy as np
import pytest

from helpers.studies import chromium
from longslam.study.report.interactive import COLOURS

pytestmark = pytest.mark.slow  # runs a study and opens its report in a browser


def test_every_local_runs_log_holds_what_ran_and_how_it_ended(study):
    out, _ = study
    # Each run's log; a run whose process died also left its console as NAME.console.log.
    logs = {path.relative_to(out / "logs").as_posix(): path.read_text() for path in (out / "logs").rglob("*.log")
            if not path.name.endswith(".console.log")}
    assert len(logs) == 8 and all(logs.values())  # on main all eight were empty
    for seed in (0, 1):
        good = logs[f"tiny/large/gridded/seed-{seed}.log"]
        assert good.startswith(f"longslam study run tiny/large/gridded/seed-{seed}: method gridded")
        assert re.search(r"finished ok after [0-9.]+ s: \d+ frames, ATE [0-9.]+ m, peak RSS \d+ MB", good)
        crashed = logs[f"tiny/large/crashy/seed-{seed}.log"]
        assert "RuntimeError: crashy fails on purpose at frame 5" in crashed and "failed after" in crashed
        died = logs[f"tiny/large/dies/seed-{seed}.log"]  # killed: what ran, and no ending
        assert died.startswith("longslam study run") and "finished" not in died and "failed" not in died


def test_the_runs_table_links_only_files_that_are_there(study):
    out, _ = study
    markdown = (out / "report.md").read_text()
    table = markdown.split("### All runs")[1].split("\n### ")[0].split("\n## ")[0]
    rows = [line for line in table.splitlines() if line.startswith("| tiny |")]
    assert len(rows) == 8
    links = re.findall(r"\[(trajectory|stats|config|log)\]\(([^)]+)\)", table)
    assert len(links) == 20 and all((out / href).is_file() and (out / href).stat().st_size > 0 for _, href in links)
    crashed = next(row for row in rows if "| crashy | 0 |" in row)
    assert "error: MethodError: method 'crashy': step() of frame 5 raised RuntimeError: crashy fails on purpose at frame 5" in crashed and "[log](logs/tiny/large/crashy/seed-0.log)" in crashed
    odometry = next(row for row in rows if "| odometry | 1 |" in row)
    cells = [c.strip() for c in odometry.strip("|").split("|")]
    header = [c.strip() for c in table.split("\n| route |")[1].splitlines()[0].strip("|").split("|")]
    values = dict(zip(["route"] + header, cells))
    # "ok, starved" when its process waited for a core (two runs at once on a loaded 2-core machine).
    assert values["status"] in ("ok", "ok, starved") and 50 < float(values["peak memory [MB]"]) < 2000
    assert float(values["ATE [m]"]) > 0 and 0.0 <= float(values["CPU wait share"]) <= 1.0
    assert values["APE RMSE [m]"] != "–" and values["time [s]"] != "–"


def test_every_seeds_trajectory_is_drawn(study):
    out, _ = study
    markdown = (out / "report.md").read_text()
    page = (out / "report.html").read_text()
    assert "one panel per seed (0, 1)" in markdown  # on main: seed 0 only
    for method in ("odometry", "gridded"):
        for seed in (0, 1):
            assert f'"name":"{method}, seed {seed} (ATE ' in page
    assert '"label":"seed 1"' in page and '"label":"all seeds"' in page  # the seed menu


@pytest.mark.skipif(chromium() is None, reason="chromium is not installed (apt-get install chromium)")
def test_a_screenshot_shows_the_runs_table_and_an_interactive_figure(study, tmp_path):
    import matplotlib.image as mpimg
    from matplotlib.colors import to_rgb

    out, _ = study
    # Only the runs table and the first interactive figure (the trajectories), as a reader
    # scrolled there would see them.
    keep = """<script>
window.addEventListener("load", () => {
  const keep = [document.getElementById("all-runs"), document.querySelector("table.runs"),
                document.querySelector("figure.interactive")];
  for (const el of Array.from(document.body.children)) { if (!keep.includes(el)) el.style.display = "none"; }
});
</script></body>"""
    page = tmp_path / "report.html"
    page.write_text((out / "report.html").read_text().replace("</body>", keep))
    shot = tmp_path / "shot.png"
    command = [
        chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run", "--hide-scrollbars",
        f"--user-data-dir={tmp_path / 'profile'}", "--window-size=1300,1400", "--virtual-time-budget=10000",
        f"--screenshot={shot}", page.as_uri(),
    ]
    subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert shot.is_file(), "chromium wrote no screenshot"
    image = mpimg.imread(shot)[..., :3]
    print(f"screenshot: {shot}")  # kept in pytest's temporary folder, to look at when this fails

    def share(colour: str, tolerance: float = 0.1) -> float:
        return float(np.mean(np.linalg.norm(image - np.asarray(to_rgb(colour)), axis=-1) < tolerance))

    # The table's grey borders and header, and the two methods' lines in plotly's figure.
    assert share("#bbbbbb", 0.05) > 0.002 and share("#eeeeee", 0.02) > 0.01
    # odometry and gridded drive the same line: odometry's (wider, under) still shows, and in the legend.
    assert share(COLOURS[0]) > 3e-5 and share(COLOURS[1]) > 3e-5
    # The floor plan's walls (black) and unknown space (grey) under them.
    assert share("#000000", 0.05) > 0.001 and share("#bfbfbf", 0.03) > 0.01
