"""Issue 21, the second battery: nothing a user types may delete their data, exhaust the machine
or hang. Each test here failed on the code before the fix it covers."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from conftest import write_tiny_sequence
from longslam.cli import main


def _one_line_error(capsys, *needles: str) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "error:" in lines[0], err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


def _tree(path: Path) -> dict[str, bytes]:
    """Every file under `path` with its content: what must survive a refused command."""
    return {str(p.relative_to(path)): p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()}


@pytest.fixture()
def seq(tmp_path) -> Path:
    return write_tiny_sequence(tmp_path / "seq", n=12)[0]


# ------------------------------------------------------------------ BAD 1: --overwrite deletes the input


def test_run_overwrite_never_deletes_its_input_sequence(seq, tmp_path, capsys):
    before = _tree(tmp_path)
    for out in (seq, tmp_path, seq / "run"):  # the input, a folder holding it, a folder inside it
        assert main(["run", "--method", "odometry", str(seq), "--out", str(out), "--overwrite"]) == 2
        _one_line_error(capsys, str(out), "input sequence")
        assert _tree(tmp_path) == before
    # through a symbolic link too: the real paths are compared
    link = tmp_path.parent / f"{tmp_path.name}-link"
    link.symlink_to(tmp_path)
    assert main(["run", "--method", "odometry", str(seq), "--out", str(link / "seq"), "--overwrite"]) == 2
    _one_line_error(capsys, "input sequence")
    assert _tree(tmp_path) == before


def test_run_overwrite_replaces_only_a_run_folder(seq, tmp_path, capsys):
    other = write_tiny_sequence(tmp_path / "other", n=5)[0]
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "thesis.tex").write_text("years of work")
    holding = tmp_path / "holding"
    assert main(["run", "--method", "odometry", str(seq), "--out", str(holding / "inner")]) == 0
    (holding / "stats.json").write_text("{}")  # looks like a run, but holds one
    (holding / "config.toml").write_text("")
    capsys.readouterr()
    for out, why in ((other, "no stats.json"), (mine, "no stats.json"), (holding, "holds a run")):
        before = _tree(out)
        assert main(["run", "--method", "odometry", str(seq), "--out", str(out), "--overwrite"]) == 2
        _one_line_error(capsys, str(out), "replaces only a run folder", why, "nothing was deleted")
        assert _tree(out) == before
    run = tmp_path / "run"
    assert main(["run", "--method", "odometry", str(seq), "--out", str(run)]) == 0
    assert main(["run", "--method", "odometry", str(seq), "--out", str(run), "--overwrite"]) == 0  # a run: replaced


def test_simulate_overwrite_replaces_only_a_sequence(tmp_path, capsys, monkeypatch):
    from longslam import recording

    monkeypatch.setattr(recording, "rendered_sequence", lambda *a, **k: pytest.fail("rendered before --out was checked"))
    seq = write_tiny_sequence(tmp_path / "seq", n=5)[0]
    (seq / "notes.txt").write_text("mine")
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "a.txt").write_text("mine")
    route = tmp_path / "r.txt"
    route.write_text("20 31.25\n22 31.25\n")
    for out, why in ((seq, "not a sequence's: notes.txt"), (mine, "no meta.json"), (tmp_path, "holds the input")):
        before = _tree(tmp_path)
        assert main(["simulate", "--route", str(route), "--out", str(out), "--overwrite"]) == 2
        _one_line_error(capsys, str(out), why)
        assert _tree(tmp_path) == before


@pytest.mark.parametrize("fmt", ["ros2", "ros1"])
def test_export_and_import_overwrite_never_delete_their_input(seq, tmp_path, capsys, fmt):
    pytest.importorskip("rosbags")
    bag = tmp_path / ("bag" if fmt == "ros2" else "seq.bag")
    assert main(["export", str(seq), "--odom-noise", "large", "--format", fmt, "--out", str(bag)]) == 0
    capsys.readouterr()
    before = _tree(tmp_path)
    if fmt == "ros2":  # a sequence is not a bag: refused, whether it is the input or not
        assert main(["export", str(seq), "--odom-noise", "large", "--out", str(seq), "--overwrite"]) == 2
        _one_line_error(capsys, "input sequence")
        assert main(["export", str(seq), "--odom-noise", "large", "--out", str(tmp_path), "--overwrite"]) == 2
        _one_line_error(capsys, "holds the input sequence")
    else:
        (tmp_path / "notes.bag").write_text("not a bag")
        before = _tree(tmp_path)
        assert main(["export", str(seq), "--odom-noise", "large", "--format", "ros1", "--out", str(tmp_path / "notes.bag"), "--overwrite"]) == 2
        _one_line_error(capsys, "not a ROS 1 bag")
    assert main(["import", str(bag), "--out", str(bag), "--overwrite"]) == 2
    _one_line_error(capsys, "input bag" if fmt == "ros2" else "is a file")
    assert _tree(tmp_path) == before
    assert main(["import", str(bag), "--out", str(seq), "--overwrite"]) == 0  # a sequence: replaced
    capsys.readouterr()
    assert main(["export", str(seq), "--odom-noise", "large", "--format", fmt, "--out", str(bag), "--overwrite"]) == 0  # a bag: replaced


def test_the_final_rename_keeps_a_folder_that_became_the_users(seq, tmp_path, monkeypatch):
    """A run checks --out again when it renames its output: a folder someone put there meanwhile stays."""
    from longslam.errors import InputError
    from longslam.run import engine
    from longslam.run.engine import run_sequence

    out = tmp_path / "run"
    run_sequence("odometry", seq, out, progress=False)
    real = engine.run_frames

    def meanwhile(*args, **kwargs):
        shutil.rmtree(out)
        out.mkdir()
        (out / "mine.txt").write_text("mine")
        return real(*args, **kwargs)

    monkeypatch.setattr(engine, "run_frames", meanwhile)
    with pytest.raises(InputError, match="replaces only a run folder"):
        run_sequence("odometry", seq, out, overwrite=True, progress=False)
    assert sorted(os.listdir(out)) == ["mine.txt"]
    assert not [p for p in tmp_path.iterdir() if ".partial-" in p.name]


# ------------------------------------------------------------------ BAD 6: output files replaced silently


def test_world_out_refuses_an_existing_file_without_overwrite(tmp_path, capsys):
    plan = tmp_path / "plan.png"
    plan.write_bytes(b"keep")
    assert main(["world", "--out", str(plan)]) == 2
    _one_line_error(capsys, str(plan), "exists already", "--overwrite")
    assert plan.read_bytes() == b"keep"
    assert main(["world", "--out", str(plan), "--overwrite"]) == 0
    assert plan.read_bytes() != b"keep"


def test_viz_file_refused_without_overwrite(seq, tmp_path, capsys):
    keep = tmp_path / "keep.rrd"
    keep.write_bytes(b"keep")
    assert main(["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "run"), "--viz", str(keep)]) == 2
    _one_line_error(capsys, "keep.rrd", "exists already", "--overwrite")
    assert keep.read_bytes() == b"keep" and not (tmp_path / "run").exists()
    (tmp_path / "rec-odometry.rrd").write_bytes(b"keep")
    assert main(["demo", "--out", str(tmp_path / "demo"), "--viz", str(tmp_path / "rec.rrd")]) == 2
    _one_line_error(capsys, "rec-odometry.rrd", "exists already")
    assert not (tmp_path / "demo").exists()


def test_viz_into_a_read_only_folder_is_a_clear_error(seq, tmp_path, capsys):
    if os.geteuid() == 0:
        pytest.skip("root writes into read-only folders")
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        assert main(["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "run"), "--viz", str(ro / "x.rrd")]) == 2
        _one_line_error(capsys, "not writable")
    finally:
        ro.chmod(0o755)


# ------------------------------------------------------------------ report: its files and its database


def _empty_study_folder(path: Path) -> Path:
    from longslam.study.database import DB_NAME, ResultsDB

    path.mkdir()
    with ResultsDB(path / DB_NAME) as db:
        db.set_study({"name": "s", "routes": [], "noise": [], "methods": [], "seeds": [0]})
    return path


def test_report_keeps_a_report_md_longslam_did_not_write(tmp_path, capsys):
    out = _empty_study_folder(tmp_path / "study")
    (out / "report.md").write_text("my notes on the study\n")
    assert main(["report", str(out)]) == 2
    _one_line_error(capsys, "report.md", "not a report longslam wrote", "--overwrite")
    assert (out / "report.md").read_text() == "my notes on the study\n"
    assert main(["report", str(out), "--overwrite"]) == 0
    assert main(["report", str(out)]) == 0  # its own report is rewritten without asking


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
    _one_line_error(capsys, "results.sqlite", "no table runs")
    assert (out / "report.md").read_text() == "# longslam study report: the last one\n"
    conn = sqlite3.connect(out / "results.sqlite")
    assert [r[0] for r in conn.execute("SELECT name FROM sqlite_master")] == ["notes"]  # nothing created
    conn.close()


def test_report_on_broken_json_names_the_run_and_column(tmp_path, capsys):
    import sqlite3

    out = _empty_study_folder(tmp_path / "study")
    conn = sqlite3.connect(out / "results.sqlite")
    conn.execute("INSERT INTO runs (key, status, route, noise, method, seed, params) "
                 "VALUES ('r/none/odometry/seed-0', 'ok', 'r', 'none', 'odometry', 0, '{broken')")
    conn.commit()
    conn.close()
    assert main(["report", str(out)]) == 2
    _one_line_error(capsys, "r/none/odometry/seed-0", "params", "not valid JSON")
