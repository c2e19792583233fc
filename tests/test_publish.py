"""scripts/publish.py: a tiny study published through the steps' own code (run, then the page from
its database), the page's stamp, and the refusals: runs of two commits, a dirty git tree."""

from __future__ import annotations

import json
import os
import sqlite3
import subprocess
from pathlib import Path

import pytest
from helpers.scripts import load_script
from helpers.studies import tiny_study_file

from longslam.run.provenance import machine, single_commit

ROOT = Path(__file__).resolve().parent.parent
publish = load_script(Path("scripts/publish.py"), "publish")


def _set_commits(study: Path, commits: list[str]) -> None:
    """Give the study's runs these commits (in key order). The checkout may have uncommitted changes
    while the tests run, so the runs' own commit may be 'abc1234+dirty', which is never published."""
    with sqlite3.connect(study / "results.sqlite") as db:
        keys = [k for (k,) in db.execute("SELECT key FROM runs ORDER BY key")]
        assert len(keys) == len(commits)
        for key, commit in zip(keys, commits):
            (text,) = db.execute("SELECT measurements FROM runs WHERE key = ?", (key,)).fetchone()
            measured = json.loads(text)
            measured["longslam_commit"] = commit
            db.execute("UPDATE runs SET measurements = ? WHERE key = ?", (json.dumps(measured), key))


@pytest.mark.slow  # runs a study end to end, twice (5 s)
def test_a_tiny_study_is_published_with_its_stamp_and_runs_of_two_commits_are_refused(
    tmp_path, render_cache, monkeypatch
):
    monkeypatch.setenv("LONGSLAM_CACHE", str(render_cache))
    study_file = tiny_study_file(tmp_path, "[0, 1]")
    said: list[str] = []
    pub = publish.Publication(ROOT, tmp_path / "work", tmp_path / "docs" / "results",
                              "python scripts/publish.py --only tiny", jobs=1, say=said.append)
    page = publish.StudyPage("tiny", study_file, "tiny.md", "A tiny study", ("What the tiny study is.",))
    out = publish.run_study_step(pub, page)
    assert any("tiny: 2 runs, 0 recorded before, 2 run now" in line for line in said)
    # A step resumes from its database: nothing runs again.
    publish.run_study_step(pub, page)
    assert any("tiny: 2 runs, 2 recorded before, 0 run now" in line for line in said)

    _set_commits(out, ["abc1234", "abc1234"])
    path = publish.publish_study(pub, page, out, 75.0)
    text = path.read_text()
    lines = text.splitlines()
    assert lines[0] == "# A tiny study"
    assert "- **Commit**: every run was made at `abc1234`" in text
    assert f"- **Machine**: {machine()}" in lines
    assert f"{os.cpu_count()} cores (" in machine() and "GiB memory" in machine()
    assert "- **Command**: `python scripts/publish.py --only tiny`" in lines
    assert f"`longslam study {study_file} --out {out} --jobs 1`" in text
    assert "- **Wall time of the step**: 75 s" in text
    assert "What the tiny study is." in text and "### Table 1: accuracy" in text
    figures = tmp_path / "docs" / "results" / "tiny-abc1234"
    pngs = sorted(p.name for p in figures.glob("*.png"))
    assert pngs and all(f"(tiny-abc1234/{name})" in text for name in pngs)

    _set_commits(out, ["abc1234", "def5678"])
    with pytest.raises(publish.PublishError, match="commits abc1234, def5678"):
        publish.publish_study(pub, page, out, 1.0)
    _set_commits(out, ["abc1234+dirty", "abc1234+dirty"])
    with pytest.raises(publish.PublishError, match=r"abc1234\+dirty"):
        publish.publish_study(pub, page, out, 1.0)
    assert path.read_text() == text  # a refused page leaves the published one as it was


def test_one_clean_commit_is_asked_of_the_runs():
    assert single_commit(["abc1234", "abc1234"], "x") == "abc1234"
    for commits in (["abc1234", "def5678"], ["abc1234", None], ["abc1234+dirty"], []):
        with pytest.raises(ValueError):
            single_commit(commits, "x")


def _git(repo: Path, *args: str) -> None:
    subprocess.run(["git", "-C", str(repo), "-c", "user.name=t", "-c", "user.email=t@t", *args], check=True,
                   capture_output=True)


def test_a_tree_with_changes_to_tracked_files_is_refused_before_any_step(tmp_path):
    repo = tmp_path / "repo"
    repo.mkdir()
    _git(repo, "init", "-q")
    (repo / "tracked.txt").write_text("one\n")
    _git(repo, "add", "tracked.txt")
    _git(repo, "commit", "-q", "-m", "one")
    ran: list[str] = []
    pub = publish.Publication(repo, tmp_path / "work", repo / "docs" / "results", "publish", say=ran.append)
    publish.RUNNERS["noted"] = lambda p: ran.append("noted") or repo
    try:
        (repo / "untracked.txt").write_text("new\n")  # untracked files do not count
        (repo / "docs" / "results").mkdir(parents=True)
        (repo / "docs" / "results" / "page.md").write_text("a page\n")
        _git(repo, "add", "docs")
        _git(repo, "commit", "-q", "-m", "a page")
        # A page an earlier step wrote at this commit: the next step may run beside it.
        (repo / "docs" / "results" / "page.md").write_text("the page written again\n")
        publish.publish(pub, ["noted"])
        assert ran.count("noted") == 1
        (repo / "tracked.txt").write_text("two\n")
        with pytest.raises(publish.PublishError, match=r"uncommitted changes \(tracked.txt\)"):
            publish.publish(pub, ["noted"])
        assert ran.count("noted") == 1  # refused before the step ran
    finally:
        del publish.RUNNERS["noted"]


def test_steps_are_named_and_run_in_the_publication_order():
    assert publish.parse_steps(None) == ["paper", "sensors", "scale", "maps"]
    assert publish.parse_steps("maps,paper") == ["paper", "maps"]
    assert publish.parse_steps("real-systems") == ["real-systems"]
    with pytest.raises(publish.PublishError, match="unknown step"):
        publish.parse_steps("paper,nope")


def _run(method, perturbation, seed, ate, *, repeat=0, status="ok", wait=0.0, stats=None):
    """A study database row as the degradation page reads it."""
    return {"route": "paper-300m", "camera_name": "camera", "sensor": "ideal", "noise": "large",
            "method": method, "method_name": method, "perturbation": perturbation, "seed": seed,
            "repeat": repeat, "status": status, "ate": ate if status == "ok" else None,
            "cpu_wait_share": wait, "measurements": {"method_stats": stats or {}}}


def test_the_degradation_page_gives_each_perturbations_median_range_and_failures(tmp_path):
    runs = [
        _run("odometry", "none", 0, 1.0), _run("odometry", "none", 1, 2.0),
        _run("odometry", "drop=0.3", 0, 1.0), _run("odometry", "drop=0.3", 1, 2.0),
        _run("keyframe", "none", 0, 0.10), _run("keyframe", "none", 1, 0.30, wait=0.5),
        _run("keyframe", "drop=0.3", 0, 1.5), _run("keyframe", "drop=0.3", 1, 0.0, status="failed"),
        _run("orbslam3", "none", 0, 0.05), _run("orbslam3", "none", 0, 0.07, repeat=1, wait=0.5),
        _run("orbslam3", "drop=0.3", 0, 0.2, stats={"maps_started": 2}),
    ]
    cells = publish.degradation_cells(runs)
    none, dropped = cells["none"], cells["drop=0.3"]
    assert none["keyframe"].ates == (0.10, 0.30) and none["keyframe"].failed == 0
    # Worse than dead reckoning on its sequence (1.5 > 1.0) and an error: both failed.
    assert dropped["keyframe"].ates == (1.5,) and dropped["keyframe"].failed == 2
    assert dropped["orbslam3"].failed == 1  # a second map
    assert none["orbslam3"].starved == 1 and none["orbslam3"].failed == 0
    # keyframe takes each frame when it is ready: a core it waited for leaves its result as it is.
    assert none["keyframe"].starved == 0
    table = "\n".join(publish.degradation_table(cells, ["odometry", "keyframe", "orbslam3"]))
    assert "| none | 1.500 [1.000-2.000] | 0.200 [0.100-0.300] | 0.060 [0.050-0.070], 1 starved |" in table
    assert "| drop=0.3 | 1.500 [1.000-2.000] | 1.500, 2/2 failed | 0.200, 1/1 failed |" in table
    assert table.index("| none |") < table.index("| drop=0.3 |")
    figures = publish.degradation_figures(cells, ["odometry", "keyframe", "orbslam3"], tmp_path)
    assert [p.name for p in figures] == ["degradation-drop.png"] and figures[0].stat().st_size > 0
    assert publish.perturbation_level("drop-burst=3") == ("drop-burst", 3.0)
    assert publish.perturbation_level("none") is None and publish.perturbation_level("blur=0.02+exposure=2") is None
    assert publish.parse_steps("degradation,paper") == ["paper", "degradation"]


def test_runs_told_the_depth_delay_are_a_row_of_their_own_and_no_figure(tmp_path):
    told = [dict(_run(m, "depth-offset=0.1", 0, ate), spec={"depth_delay": 0.1})
            for m, ate in (("odometry", 1.0), ("keyframe", 0.2))]
    runs = [_run("odometry", "depth-offset=0.1", 0, 1.0), _run("keyframe", "depth-offset=0.1", 0, 1.4), *told,
            _run("odometry", "none", 0, 1.0), _run("keyframe", "none", 0, 0.1)]
    cells = publish.degradation_cells(runs)
    row = "depth-offset=0.1, told depth_delay 0.1 s"
    assert publish.degradation_row(told[1]) == row
    assert cells[row]["keyframe"].ates == (0.2,) and cells["depth-offset=0.1"]["keyframe"].ates == (1.4,)
    table = publish.degradation_table(cells, ["odometry", "keyframe"])
    assert [line.split(" | ")[0] for line in table[2:]] == ["| none", "| depth-offset=0.1", f"| {row}"]
    figures = publish.degradation_figures(cells, ["odometry", "keyframe"], tmp_path)
    assert [p.name for p in figures] == ["degradation-depth-offset.png"]  # the told row is not a level
    assert publish.perturbation_level(row) is None


@pytest.mark.slow  # runs a study end to end (2.4 s)
def test_a_tiny_perturbation_study_is_published_as_a_degradation_page(tmp_path, render_cache, monkeypatch):
    monkeypatch.setenv("LONGSLAM_CACHE", str(render_cache))
    (tmp_path / "r.txt").write_text("20 31.25\n21 31.25\n")
    study_file = tmp_path / "d.toml"
    study_file.write_text('routes = ["r.txt"]\nnoise = ["none"]\nmethods = ["odometry"]\nseeds = [0]\n'
                          'perturbations = ["none", "drop=0.3"]\n[camera]\nwidth = 16\nheight = 12\n')
    pub = publish.Publication(ROOT, tmp_path / "work", tmp_path / "docs" / "results",
                              "python scripts/publish.py --only degradation", jobs=1, say=lambda text: None)
    out = publish.run_study_step(pub, publish.StudyPage("degradation", study_file, "", ""))
    _set_commits(out, ["abc1234", "abc1234"])
    path = publish.publish_degradation(pub, [out], 12.0, ["longslam study d.toml"])
    text = path.read_text()
    assert text.startswith("# How each method degrades\n")
    assert "- **Commit**: every run was made at `abc1234`" in text
    assert "| perturbation | odometry |" in text and "| none | " in text and "| drop=0.3 | " in text
    assert "(degradation-abc1234/degradation-drop.png)" in text
    assert (tmp_path / "docs" / "results" / "degradation-abc1234" / "degradation-drop.png").is_file()


def test_orbslam3_left_out_by_the_flag_says_so_plugin_or_not(tmp_path, monkeypatch):
    import longslam.slam.catalog as catalog

    pub = publish.Publication(ROOT, tmp_path / "work", tmp_path / "docs" / "results", "publish")
    monkeypatch.setattr(catalog, "method_names", lambda: ["keyframe", "orbslam3"])
    assert publish.orbslam3_left_out(pub, "it did not run") is None  # installed and not left out: it runs
    pub.without_orbslam3 = True
    note = publish.orbslam3_left_out(pub, "it did not run")
    assert note is not None and "--without-orbslam3" in note and "3 cores" in note and note.endswith("it did not run.")
    pub.without_orbslam3 = False
    monkeypatch.setattr(catalog, "method_names", lambda: ["keyframe"])
    assert "was not installed" in publish.orbslam3_left_out(pub, "it did not run")
