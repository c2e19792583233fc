"""What `longslam report` makes of a study folder it cannot fully use: a database without its
tables is refused, broken JSON is named by run and column, and figures left out are said with why."""

from __future__ import annotations

import shutil

import pytest

from helpers.cli_checks import one_line_error
from helpers.studies import empty_study_folder, tiny_study_file
from longslam.cli.main import main


def test_report_on_a_database_without_its_tables_refuses(tmp_path, capsys):
    import sqlite3

    out = tmp_path / "study"
    out.mkdir()
    conn = sqlite3.connect(out / "results.sqlite")
    conn.execute("CREATE TABLE notes (x TEXT)")
    conn.commit()
    conn.close()
    (out / "report.md").write_text("# longslam study report: the last one\n")
    assert main(["report", str(out)]) == 2
    one_line_error(capsys, "results.sqlite", "no table runs")
    assert (out / "report.md").read_text() == "# longslam study report: the last one\n"
    conn = sqlite3.connect(out / "results.sqlite")
    assert [r[0] for r in conn.execute("SELECT name FROM sqlite_master")] == ["notes"]  # nothing created
    conn.close()


def test_report_on_broken_json_names_the_run_and_column(tmp_path, capsys):
    import sqlite3

    out = empty_study_folder(tmp_path / "study")
    conn = sqlite3.connect(out / "results.sqlite")
    conn.execute("INSERT INTO runs (key, status, route, noise, method, seed, params) "
                 "VALUES ('r/none/odometry/seed-0', 'ok', 'r', 'none', 'odometry', 0, '{broken')")
    conn.commit()
    conn.close()
    assert main(["report", str(out)]) == 2
    one_line_error(capsys, "r/none/odometry/seed-0", "params", "not valid JSON")


@pytest.mark.slow
def test_report_says_which_figures_it_left_out_and_why(tmp_path, capsys):
    study = tiny_study_file(tmp_path, "1")
    out = tmp_path / "out"
    assert main(["study", str(study), "--out", str(out), "--no-report"]) == 0
    shutil.rmtree(out / "runs")
    capsys.readouterr()
    assert main(["report", str(out)]) == 0
    err = capsys.readouterr().err
    assert "note: trajectory of r/none/odometry/seed-0 left out of the trajectory figure" in err
    assert "Left out: trajectory of r/none/odometry/seed-0" in (out / "report.md").read_text()
    (grid,) = (out / "worlds").iterdir()
    grid.write_bytes(grid.read_bytes()[:100])  # a truncated grid.npz
    assert main(["report", str(out)]) == 0
    err = capsys.readouterr().err
    assert "note: no figures: the world's ground-truth grid cannot be read" in err and str(grid) in err
