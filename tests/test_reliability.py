"""Issue 21, the second battery: nothing a user types may delete their data, exhaust the machine
or hang. Each test here failed on the code before the fix it covers."""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

import pytest

from conftest import one_line_error, write_tiny_sequence
from longslam.cli.main import main



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
        one_line_error(capsys, str(out), "input sequence")
        assert _tree(tmp_path) == before
    # through a symbolic link too: the real paths are compared
    link = tmp_path.parent / f"{tmp_path.name}-link"
    link.symlink_to(tmp_path)
    assert main(["run", "--method", "odometry", str(seq), "--out", str(link / "seq"), "--overwrite"]) == 2
    one_line_error(capsys, "input sequence")
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
        one_line_error(capsys, str(out), "replaces only a run folder", why, "nothing was deleted")
        assert _tree(out) == before
    run = tmp_path / "run"
    assert main(["run", "--method", "odometry", str(seq), "--out", str(run)]) == 0
    assert main(["run", "--method", "odometry", str(seq), "--out", str(run), "--overwrite"]) == 0  # a run: replaced


def test_simulate_overwrite_replaces_only_a_sequence(tmp_path, capsys, monkeypatch):
    from longslam.sim import simulate as recording

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
        one_line_error(capsys, str(out), why)
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
        one_line_error(capsys, "input sequence")
        assert main(["export", str(seq), "--odom-noise", "large", "--out", str(tmp_path), "--overwrite"]) == 2
        one_line_error(capsys, "holds the input sequence")
    else:
        (tmp_path / "notes.bag").write_text("not a bag")
        before = _tree(tmp_path)
        assert main(["export", str(seq), "--odom-noise", "large", "--format", "ros1", "--out", str(tmp_path / "notes.bag"), "--overwrite"]) == 2
        one_line_error(capsys, "not a ROS 1 bag")
    assert main(["import", str(bag), "--out", str(bag), "--overwrite"]) == 2
    one_line_error(capsys, "input bag" if fmt == "ros2" else "is a file")
    assert _tree(tmp_path) == before
    assert main(["import", str(bag), "--out", str(seq), "--overwrite"]) == 0  # a sequence: replaced
    capsys.readouterr()
    assert main(["export", str(seq), "--odom-noise", "large", "--format", fmt, "--out", str(bag), "--overwrite"]) == 0  # a bag: replaced


def test_the_final_rename_keeps_a_folder_that_became_the_users(seq, tmp_path, monkeypatch):
    """A run checks --out again when it renames its output: a folder someone put there meanwhile stays."""
    from longslam.core.errors import InputError
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
    keep = b"\x89PNG\r\n\x1a\nkeep"  # an image: --overwrite replaces only one (test_overwrite_kinds.py)
    plan.write_bytes(keep)
    assert main(["world", "--out", str(plan)]) == 2
    one_line_error(capsys, str(plan), "exists already", "--overwrite")
    assert plan.read_bytes() == keep
    assert main(["world", "--out", str(plan), "--overwrite"]) == 0
    assert plan.read_bytes() != keep


def test_viz_file_refused_without_overwrite(seq, tmp_path, capsys):
    keep = tmp_path / "keep.rrd"
    keep.write_bytes(b"keep")
    assert main(["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "run"), "--viz", str(keep)]) == 2
    one_line_error(capsys, "keep.rrd", "exists already", "--overwrite")
    assert keep.read_bytes() == b"keep" and not (tmp_path / "run").exists()
    (tmp_path / "rec-odometry.rrd").write_bytes(b"keep")
    assert main(["demo", "--out", str(tmp_path / "demo"), "--viz", str(tmp_path / "rec.rrd")]) == 2
    one_line_error(capsys, "rec-odometry.rrd", "exists already")
    assert not (tmp_path / "demo").exists()


def test_viz_into_a_read_only_folder_is_a_clear_error(seq, tmp_path, capsys):
    if os.geteuid() == 0:
        pytest.skip("root writes into read-only folders")
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        assert main(["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "run"), "--viz", str(ro / "x.rrd")]) == 2
        one_line_error(capsys, "not writable")
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
    one_line_error(capsys, "report.md", "not a report longslam wrote", "--overwrite")
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
    one_line_error(capsys, "results.sqlite", "no table runs")
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
    one_line_error(capsys, "r/none/odometry/seed-0", "params", "not valid JSON")


# ------------------------------------------------------------------ BAD 3: seeds SQLite cannot store


def _study_file(tmp_path: Path, seeds: str, extra: str = "", name: str = "s.toml") -> Path:
    (tmp_path / "r.txt").write_text("20 31.25\n21 31.25\n")
    study = tmp_path / name
    study.write_text(f'routes = ["r.txt"]\nnoise = ["none"]\nmethods = ["odometry"]\nseeds = {seeds}\n'
                     '[camera]\nwidth = 16\nheight = 12\n' + extra)
    return study


@pytest.mark.parametrize("seeds, needle", [
    ("[1180591620717411303424]", "seeds[0]: seed 1180591620717411303424"),
    ("[0, 9223372036854775808]", "seeds[1]: seed 9223372036854775808"),
])
def test_a_seed_sqlite_cannot_store_is_refused_in_a_study(tmp_path, capsys, seeds, needle):
    study = _study_file(tmp_path, seeds)
    assert main(["study", str(study), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, str(study), needle, "2**63 - 1")
    assert not (tmp_path / "out").exists()


def test_the_largest_seed_is_drawn_and_recorded(tmp_path):
    from longslam.study.database import ResultsDB
    from longslam.study.config import load_study
    from longslam.study.spec import plan_runs
    from longslam.study.record import RunRecord

    config = load_study(_study_file(tmp_path, "[9223372036854775807]"))
    (spec,) = plan_runs(config)
    with ResultsDB(tmp_path / "db.sqlite") as db:  # the OverflowError of issue 21 came from here
        db.record(spec, RunRecord.failed("x"), None)
        assert db.runs()[0]["seed"] == 2**63 - 1


@pytest.mark.parametrize("command", ["simulate", "demo"])
def test_a_seed_out_of_range_on_the_command_line(tmp_path, capsys, monkeypatch, command):
    from longslam.sim import simulate as recording

    monkeypatch.setattr(recording, "rendered_sequence", lambda *a, **k: pytest.fail("rendered before the seed was checked"))
    args = ["--route", "demo"] if command == "simulate" else []
    assert main([command, *args, "--seed", str(2**64), "--out", str(tmp_path / "x")]) == 2
    one_line_error(capsys, str(2**64), "2**63 - 1")
    assert not (tmp_path / "x").exists()


# ------------------------------------------------------------------ BAD 2: values that eat the machine


@pytest.mark.parametrize("method, param, needle", [
    ("keyframe", "grid_cell=0.000001", "grid_cell must be from 0.01 to 10 m"),
    ("keyframe", "max_features=1000000000", "max_features must be from 1 to 100000"),
    ("keyframe", "cloud_voxel=1e-5", "cloud_voxel"),
    ("submap", "voxel_size=0.001", "voxel_size must be from 0.02 to 5 m"),
    ("submap", "grid_resolution=0.0001", "grid_resolution"),
    ("submap", "truncation=100", "truncation (100) may be at most 40 x voxel_size (8 m)"),
])
def test_size_like_parameters_are_refused_before_the_run(seq, tmp_path, capsys, method, param, needle):
    assert main(["run", "--method", method, str(seq), "--out", str(tmp_path / "run"), "--param", param]) == 2
    one_line_error(capsys, needle, "100" if "truncation" in param else "got")
    assert not (tmp_path / "run").exists()


def test_a_huge_camera_is_a_clear_error_not_a_memory_error(tmp_path, capsys, monkeypatch):
    from longslam.sim import simulate as recording

    monkeypatch.setattr(recording, "rendered_sequence", lambda *a, **k: pytest.fail("rendered a huge camera"))
    assert main(["simulate", "--route", "demo", "--width", "100000", "--height", "100000", "--out", str(tmp_path / "s")]) == 2
    one_line_error(capsys, "width must be at most 7680 pixels", "100000")
    assert main(["simulate", "--route", "demo", "--width", "7680", "--height", "7680", "--out", str(tmp_path / "s")]) == 2
    one_line_error(capsys, "7680 x 7680 = 58982400 pixels", "GB")
    assert not (tmp_path / "s").exists()


def test_an_absurd_study_grid_is_refused_with_its_count_before_anything(tmp_path, capsys):
    study = _study_file(tmp_path, "1000000000")
    assert main(["study", str(study), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "seeds", "1000000000", "100000")
    study = _study_file(tmp_path, "30000")
    text = study.read_text().replace('noise = ["none"]', 'noise = ["none", "small", "large", "xlarge"]')
    study.write_text(text)
    assert main(["study", str(study), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "1 route x 4 noise levels x 1 method x 30000 seeds = 120000 runs", "100000")
    assert not (tmp_path / "out").exists()


def test_a_study_shows_its_run_count_first(tmp_path, capsys):
    study = _study_file(tmp_path, "2")
    assert main(["study", str(study), "--out", str(tmp_path / "out"), "--no-report"]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0] == "study s: 1 route x 1 noise level x 1 method x 2 seeds = 2 runs"


# ------------------------------------------------------------------ BAD 4: two studies in one folder


def test_a_different_study_into_a_study_folder_is_refused_unless_extended(tmp_path, capsys):
    from longslam.study.database import ResultsDB

    a = _study_file(tmp_path, "1", name="a.toml")
    out = tmp_path / "out"
    assert main(["study", str(a), "--out", str(out), "--no-report"]) == 0
    assert main(["study", str(a), "--out", str(out), "--no-report"]) == 0  # the same study: resumed
    b = _study_file(tmp_path, "[1]", name="b.toml")
    capsys.readouterr()
    before = _tree(out)
    assert main(["study", str(b), "--out", str(out), "--no-report"]) == 2
    line = one_line_error(capsys, str(out), "study 'a'", "study 'b'", "name, seeds", "--extend")
    assert "1 seed)" in line
    assert _tree(out) == before
    assert main(["study", str(b), "--out", str(out), "--no-report", "--extend"]) == 0
    with ResultsDB(out / "results.sqlite") as db:
        assert db.study()["name"] == "a" and db.study()["seeds"] == [0, 1] and db.count() == 2


# ------------------------------------------------------------------ BAD 5: Ray that never answers


def test_address_without_ray_is_refused_before_anything(tmp_path, capsys):
    study = _study_file(tmp_path, "1")
    assert main(["study", str(study), "--out", str(tmp_path / "out"), "--address", "127.0.0.1:6379"]) == 2
    one_line_error(capsys, "--address 127.0.0.1:6379 is for --executor ray")
    assert not (tmp_path / "out").exists()


def test_ray_address_that_refuses_is_a_clear_error_and_creates_nothing(tmp_path, capsys):
    pytest.importorskip("ray")
    import socket
    import time

    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    study = _study_file(tmp_path, "1")
    t0 = time.monotonic()
    assert main(["study", str(study), "--out", str(tmp_path / "out"), "--executor", "ray",
                 "--address", f"127.0.0.1:{port}"]) == 2
    assert time.monotonic() - t0 < 30
    one_line_error(capsys, f"127.0.0.1:{port}", "no Ray cluster answered")
    assert not (tmp_path / "out").exists()


def test_ray_init_that_hangs_is_given_up(tmp_path, capsys, monkeypatch):
    ray = pytest.importorskip("ray")
    import threading
    import socket

    from longslam.study import backends

    monkeypatch.setattr(backends, "RAY_CONNECT_TIMEOUT_S", 0.5)
    release = threading.Event()
    monkeypatch.setattr(ray, "init", lambda **kw: release.wait(30))  # as ray.init retrying an address
    listener = socket.socket()  # answers TCP, never Ray
    listener.bind(("127.0.0.1", 0))
    listener.listen()
    try:
        study = _study_file(tmp_path, "1")
        address = f"127.0.0.1:{listener.getsockname()[1]}"
        assert main(["study", str(study), "--out", str(tmp_path / "out"), "--executor", "ray", "--address", address]) == 2
        one_line_error(capsys, address, "did not start or answer")
        assert not (tmp_path / "out").exists()
    finally:
        release.set()
        listener.close()


def test_a_ray_client_address_without_ray_client_is_a_clear_error(tmp_path, capsys):
    pytest.importorskip("ray")
    import importlib.util

    if importlib.util.find_spec("grpc") is not None:
        pytest.skip("Ray Client is installed here")
    study = _study_file(tmp_path, "1")
    assert main(["study", str(study), "--out", str(tmp_path / "out"), "--executor", "ray", "--address", "ray://head:10001"]) == 2
    one_line_error(capsys, "ray://head:10001", "ray[client]")
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------ POOR: tracebacks become clear errors


def test_viz_live_without_a_viewer_or_a_display_is_a_clear_error(seq, tmp_path, capsys, monkeypatch):
    pytest.importorskip("rerun")
    import shutil as shutil_module

    from longslam.viz import live

    monkeypatch.setattr(live, "_viewer_listening", lambda port=9876: False)
    monkeypatch.setattr(shutil_module, "which", lambda *a, **k: None)
    assert main(["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "run"), "--viz"]) == 2
    one_line_error(capsys, "rerun viewer", "not on PATH", "--viz run.rrd")
    monkeypatch.undo()
    monkeypatch.setattr(live, "_viewer_listening", lambda port=9876: False)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "run"), "--viz"]) == 2
    one_line_error(capsys, "no display", "--viz run.rrd")
    assert not (tmp_path / "run").exists()


def _longslam(*args: str, env: dict | None = None, cwd: Path | None = None):
    import subprocess
    import sys

    return subprocess.run([sys.executable, "-m", "longslam", *args], capture_output=True, cwd=cwd,
                          env={**os.environ, **(env or {})}, timeout=120)


def test_non_ascii_paths_under_a_c_locale_and_paths_that_are_not_utf8(tmp_path):
    seq = write_tiny_sequence(tmp_path / "séquence", n=8)[0]
    c_locale = {"LC_ALL": "C", "LANG": "C", "PYTHONUTF8": "0", "PYTHONCOERCECLOCALE": "0"}
    done = _longslam("run", "--method", "odometry", str(seq), "--out", str(tmp_path / "exécution"), env=c_locale)
    assert done.returncode == 0, done.stderr.decode(errors="replace")
    assert b"Traceback" not in done.stderr
    assert (tmp_path / "exécution" / "config.toml").is_file()
    raw = os.fsencode(tmp_path) + b"/run\xff"  # not valid UTF-8
    done = _longslam("run", "--method", "odometry", str(seq), "--out", os.fsdecode(raw))
    assert done.returncode == 0, done.stderr.decode(errors="replace")
    assert os.path.isfile(raw + b"/stats.json")


# ------------------------------------------------------------------ POOR: nonsense accepted silently


def test_index_files_that_disagree_get_a_note_with_counts(tmp_path, capsys):
    seq = write_tiny_sequence(tmp_path / "seq", n=10)[0]
    lines = (seq / "depth.txt").read_text().splitlines()
    (seq / "depth.txt").write_text("\n".join(lines[:-3]) + "\n")  # three colour images without depth
    gt = (seq / "groundtruth.txt").read_text().splitlines()
    (seq / "groundtruth.txt").write_text("\n".join(gt[:-5]) + "\n")  # ground truth for part only
    assert main(["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "run")]) == 0
    err = capsys.readouterr().err
    assert "3 of 10 colour images in rgb.txt have no depth image" in err
    assert "groundtruth.txt has no pose within 0.02 s for 2 of 7 frames" in err
    pytest.importorskip("rosbags")
    assert main(["export", str(seq), "--format", "ros2", "--odom-noise", "none", "--out", str(tmp_path / "bag")]) == 0
    assert "3 of 10 colour images in rgb.txt have no depth image" in capsys.readouterr().err  # export says so too


def test_a_principal_point_outside_the_image_is_refused(seq, tmp_path, capsys):
    assert main(["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "r"), "--intrinsics", "10,10,800,6"]) == 2
    one_line_error(capsys, "--intrinsics", "principal point", "(800, 6)", "16 x 12")
    import json

    camera = json.loads((seq / "camera.json").read_text())
    (seq / "camera.json").write_text(json.dumps({**camera, "cy": -50}))
    assert main(["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "r")]) == 2
    one_line_error(capsys, "camera.json", "principal point")


def test_a_negative_intrinsic_gets_the_intrinsics_message_not_argparses(seq, tmp_path, capsys):
    assert main(["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "r"), "--intrinsics", "-40,40,8,6"]) == 2
    one_line_error(capsys, "--intrinsics '-40,40,8,6'", "fx and fy positive")


def test_evaluate_warns_on_partial_coverage_and_on_another_sequence(tmp_path, capsys):
    import json

    seq = write_tiny_sequence(tmp_path / "seq", n=20)[0]
    other = write_tiny_sequence(tmp_path / "other", n=20, seed=1)[0]
    assert main(["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "run")]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(tmp_path / "run"), str(seq), "--json"]) == 0
    captured = capsys.readouterr()
    assert "warning" not in captured.err
    assert json.loads(captured.out)["matched_share_estimate"] == 1.0
    assert main(["evaluate", str(tmp_path / "run"), str(other)]) == 0
    assert "ran on the sequence" in capsys.readouterr().err
    half = tmp_path / "half.txt"
    half.write_text("".join((seq / "groundtruth.txt").read_text().splitlines(keepends=True)[:11]))
    assert main(["evaluate", str(tmp_path / "run"), str(half), "--json"]) == 0
    captured = capsys.readouterr()
    assert "only 10 of 20 poses" in captured.err and "(50%)" in captured.err
    assert json.loads(captured.out)["matched_share_estimate"] == 0.5


# ------------------------------------------------------------------ POOR: leftovers of killed processes


def test_a_same_host_partial_whose_process_is_gone_is_removed_at_once(tmp_path):
    import subprocess

    from longslam.io.partials import clean_stale_partials, host_tag, partial_path

    proc = subprocess.Popen(["true"])
    proc.wait()
    mine = partial_path(tmp_path / "run", proc.pid)  # just written: no idle wait on this machine
    assert host_tag() in mine.name and mine.name.startswith(".run.partial-")
    mine.mkdir()
    alive = partial_path(tmp_path / "busy")  # this process's
    alive.mkdir()
    elsewhere = tmp_path / f".run2.partial-{proc.pid}@another_machine"
    elsewhere.mkdir()
    assert clean_stale_partials(tmp_path) == [mine]
    assert alive.exists() and elsewhere.exists()
    old = time.time() - 2 * 24 * 3600
    os.utime(elsewhere, (old, old))
    assert clean_stale_partials(tmp_path) == [elsewhere]


@pytest.mark.parametrize("text, needle", [
    ("20 31.25\n20 31.25\n", "all the same point"),
    ("20 31.25\nnan 31.25\n", "waypoint 1 (nan, 31.25) is not a point"),
])
def test_a_route_that_goes_nowhere_is_refused(tmp_path, capsys, monkeypatch, text, needle):
    monkeypatch.setenv("LONGSLAM_CACHE", str(tmp_path / "cache"))
    route = tmp_path / "r.txt"
    route.write_text(text)
    assert main(["simulate", "--route", str(route), "--out", str(tmp_path / "s")]) == 2
    one_line_error(capsys, needle)
    assert not (tmp_path / "s").exists()


def test_a_camera_above_the_ceiling_is_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("LONGSLAM_CACHE", str(tmp_path / "cache"))
    assert main(["simulate", "--route", "demo", "--camera-height", "5", "--width", "16", "--height", "12",
                 "--out", str(tmp_path / "s")]) == 2
    one_line_error(capsys, "camera height 5 m", "over the ceiling")
    assert not (tmp_path / "s").exists() and not (tmp_path / "cache").exists()
    study = _study_file(tmp_path, "1", "camera_height = 5\n")
    assert main(["study", str(study), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "camera.camera_height", "over the ceiling")
    assert not (tmp_path / "out").exists()
    named = study.read_text().replace("[camera]", "[cameras.tall]")
    (tmp_path / "named.toml").write_text(named)
    assert main(["study", str(tmp_path / "named.toml"), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "cameras.tall.camera_height", "over the ceiling")  # the table the height is in


def test_a_study_camera_string_is_not_coerced_to_a_number(tmp_path, capsys):
    study = _study_file(tmp_path, "1").read_text().replace("width = 16", 'width = "16"')
    (tmp_path / "s.toml").write_text(study)
    assert main(["study", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "camera.width: '16'", "expected a whole number, got a string")


def test_a_study_method_parameter_string_is_not_coerced_to_a_number(tmp_path, capsys):
    """As for [camera]: in a TOML file a quoted number is a mistake, where --param text is converted."""
    study = _study_file(tmp_path, "1").read_text().replace('methods = ["odometry"]', 'methods = ["keyframe"]')
    (tmp_path / "s.toml").write_text(study + '[params.keyframe]\nmax_features = "500"\n')
    assert main(["study", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "params.keyframe", "max_features='500'", "expected a whole number, got a string")
    assert not (tmp_path / "out").exists()


def test_a_variant_listed_in_methods_is_named_a_variant(tmp_path, capsys):
    study = _study_file(tmp_path, "1").read_text().replace('methods = ["odometry"]', 'methods = ["odometry", "odo2"]')
    (tmp_path / "s.toml").write_text(study + '[variants.odo2]\nmethod = "odometry"\n')
    assert main(["study", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out")]) == 2
    one_line_error(capsys, "methods[1]", "'odo2' is a variant", "remove it from methods")


@pytest.mark.parametrize("value, needle", [("file", "is a file; expected a folder"), ("", None)])
def test_longslam_cache_that_is_a_file_or_empty(tmp_path, capsys, monkeypatch, value, needle):
    from longslam.sim.simulate import cache_root

    monkeypatch.chdir(tmp_path)
    if value == "file":
        (tmp_path / "file").write_text("x")
        monkeypatch.setenv("LONGSLAM_CACHE", str(tmp_path / "file"))
        assert main(["simulate", "--route", "demo", "--out", str(tmp_path / "s")]) == 2
        one_line_error(capsys, "LONGSLAM_CACHE=", needle)
    else:
        monkeypatch.setenv("LONGSLAM_CACHE", "")
        monkeypatch.setenv("HOME", str(tmp_path / "home"))
        assert cache_root() == tmp_path / "home" / ".cache" / "longslam"  # not the current folder


def test_ros2_folder_without_metadata_and_one_topic_in_two_roles(seq, tmp_path, capsys):
    pytest.importorskip("rosbags")
    bag = tmp_path / "bag"
    assert main(["export", str(seq), "--odom-noise", "large", "--out", str(bag)]) == 0
    capsys.readouterr()
    assert main(["import", str(bag), "--out", str(tmp_path / "x"), "--odom", "/groundtruth", "--groundtruth", "/groundtruth"]) == 2
    one_line_error(capsys, "--groundtruth /groundtruth is also the --odom topic")
    (bag / "metadata.yaml").unlink()
    assert main(["import", str(bag), "--out", str(tmp_path / "x")]) == 2
    one_line_error(capsys, f"bag folder {bag} has no metadata.yaml")


def test_units_mm_on_a_metre_mesh_says_so(tmp_path, capsys):
    pytest.importorskip("trimesh")
    from longslam.world.wing_building import write_building

    ply, _ = write_building(tmp_path / "b")
    assert main(["world", "--world", str(ply), "--units", "mm", "--out", str(tmp_path / "p.png")]) == 2
    line = one_line_error(capsys, "too small to be a building", "leave out --units")
    assert "--floor" not in line


def test_report_says_which_figures_it_left_out_and_why(tmp_path, capsys):
    study = _study_file(tmp_path, "1")
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


def test_a_walls_only_mesh_is_said_to_have_no_floor(tmp_path, capsys):
    trimesh = pytest.importorskip("trimesh")
    import numpy as np

    corners = [(0, 0), (10, 0), (10, 8), (0, 8), (0, 0)]
    quads = [np.array([[x0, y0, 0], [x1, y1, 0], [x1, y1, 3], [x0, y0, 3]], float)
             for (x0, y0), (x1, y1) in zip(corners[:-1], corners[1:])]
    k = 4 * np.arange(len(quads))[:, None]
    mesh = tmp_path / "walls.ply"
    trimesh.Trimesh(np.concatenate(quads), np.concatenate([k + [0, 1, 2], k + [0, 2, 3]]), process=False).export(mesh)
    assert main(["world", "--world", str(mesh), "--floor", "0", "--out", str(tmp_path / "p.png")]) == 2
    one_line_error(capsys, "no floor surface at height 0.000 m", "walls only")


def test_vocabulary_build_never_writes_into_its_input_sequence(seq, tmp_path, capsys):
    before = _tree(seq)
    for out in (seq / "rgb.txt", seq / "voc.txt"):
        assert main(["vocabulary", "build", "--sequence", str(seq), "--out", str(out), "--overwrite"]) == 2
        one_line_error(capsys, str(out), "inside the input")
        assert _tree(seq) == before
    assert main(["vocabulary", "build", "--sequence", str(seq), "--out", str(tmp_path / "v.txt"),
                 "--seed", str(2**64)]) == 2
    one_line_error(capsys, "--seed", "2**63 - 1")


def test_orbslam3_refuses_images_it_would_crash_on(seq, tmp_path, capsys):
    pytest.importorskip("longslam_orbslam3", reason="the orbslam3 plugin is not installed")
    # 16 x 12: ORB-SLAM3 itself stopped with "vector::_M_default_append" (or a segfault) on such images
    assert main(["run", "--method", "orbslam3", str(seq), "--out", str(tmp_path / "run")]) == 2
    one_line_error(capsys, "16 x 12 images are too small for ORB-SLAM3", "at least 120 pixels")
    assert not (tmp_path / "run").exists()
