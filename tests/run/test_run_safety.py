"""`run`'s output folder: never replace another run's folder, name final paths, measure the whole run."""

import json
import subprocess
import sys
import textwrap

import pytest

from longslam.run import engine
from longslam.cli.main import main
from longslam.core.errors import InputError
from longslam.io.atomic import name_final_folder
from longslam.run.scored_run import run_named

pytestmark = pytest.mark.slow  # runs the CLI in processes

N = 20  # frames of the tiny sequence (conftest.tiny_sequence)



@pytest.fixture(scope="module")
def sequence(tiny_sequence):
    return tiny_sequence


def test_a_run_never_replaces_a_folder_another_run_finished_meanwhile(sequence, tmp_path, monkeypatch):
    out = tmp_path / "run"
    real = engine.run_frames

    def other_run_finishes_first(*args, **kwargs):
        result = real(*args, **kwargs)
        out.mkdir()
        (out / "trajectory.txt").write_text("the other run's\n")
        return result

    monkeypatch.setattr(engine, "run_frames", other_run_finishes_first)
    with pytest.raises(InputError, match="written by another process while this one ran"):
        run_named("odometry", sequence, out, progress=False)
    assert (out / "trajectory.txt").read_text() == "the other run's\n"
    assert sorted(p.name for p in out.iterdir()) == ["trajectory.txt"]
    assert [p.name for p in tmp_path.iterdir()] == ["run"]  # no partial folder left


def test_two_runs_into_one_folder_at_once_one_wins(sequence, tmp_path):
    out = tmp_path / "run"
    command = [sys.executable, "-m", "longslam", "run", "--method", "odometry", str(sequence), "--out", str(out)]
    procs = [subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    results = [(p.wait(), p.stderr.read()) for p in procs]
    codes = sorted(code for code, _ in results)
    assert codes == [0, 2], results
    loser = next(err for code, err in results if code == 2)
    assert str(out) in loser and "Traceback" not in loser
    assert json.loads((out / "stats.json").read_text())["frames"] == N
    assert [p.name for p in tmp_path.iterdir()] == ["run"]


def test_overwrite_replaces_a_finished_folder(sequence, tmp_path):
    # A finished run (stats.json and config.toml) is replaced; any other folder is not.
    out = tmp_path / "run"
    run_named("odometry", sequence, out, progress=False)
    (out / "old.txt").write_text("old")
    run_named("odometry", sequence, out, overwrite=True, progress=False)
    assert not (out / "old.txt").exists() and (out / "stats.json").is_file()
    assert [p.name for p in tmp_path.iterdir()] == ["run"]


def test_stats_name_the_final_folder_not_the_partial_one(tmp_path):
    figures = {"method_stats": {"database": str(tmp_path / ".run.partial-7" / "memory.db"), "n": 3}, "x": ["a"]}
    named = name_final_folder(figures, tmp_path / ".run.partial-7", tmp_path / "run")
    assert named["method_stats"]["database"] == str(tmp_path / "run" / "memory.db")
    assert named["x"] == ["a"] and named["method_stats"]["n"] == 3


@pytest.mark.parametrize("kind", ["file", "symlink", "under_a_file"])
def test_a_bad_out_is_refused_before_the_first_frame(sequence, tmp_path, monkeypatch, capsys, kind):
    (tmp_path / "afile").write_text("x")
    out = {"file": tmp_path / "afile", "under_a_file": tmp_path / "afile" / "run", "symlink": tmp_path / "link"}[kind]
    if kind == "symlink":
        out.symlink_to(tmp_path / "elsewhere")
    monkeypatch.setattr(engine, "run_frames", lambda *a, **k: pytest.fail("frames ran before --out was checked"))
    assert main(["run", "--method", "odometry", str(sequence), "--out", str(out), "--overwrite"]) == 2
    err = capsys.readouterr().err
    assert str(out) in err and "Traceback" not in err


def test_peak_memory_is_the_whole_runs(sequence, tmp_path):
    """The peak in stats.json covers writing the results: here writing the trajectory takes 300 MB.
    The kernel's figure for the whole process, seen from its parent, is the reference."""
    out = tmp_path / "run"
    script = textwrap.dedent(f"""
        import numpy as np
        from longslam.run import folder, scored_run
        real = folder.write_tum
        def heavy(*args):
            block = np.ones(40_000_000)  # 320 MB, touched
            real(*args)
            del block
        folder.write_tum = heavy
        scored_run.run_named("odometry", {str(sequence)!r}, {str(out)!r}, progress=False)
    """)
    # The kernel's peak of a process that was forked (or vforked) from a big one starts at the
    # parent's resident size, and exec keeps it: a run started straight from pytest (hundreds of MB
    # by now) would be charged pytest's memory. A small Python in between starts the run and
    # reports the run's own figure.
    launcher = textwrap.dedent("""
        import os, subprocess, sys
        proc = subprocess.Popen([sys.executable, "-c", sys.argv[1]])
        _, status, usage = os.wait4(proc.pid, 0)
        print(os.waitstatus_to_exitcode(status), usage.ru_maxrss * 1024)
    """)
    done = subprocess.run([sys.executable, "-c", launcher, script], capture_output=True, text=True, check=True)
    returncode, kernel_peak = (int(v) for v in done.stdout.split())
    assert returncode == 0, done.stderr
    reported = json.loads((out / "stats.json").read_text())["peak_rss_bytes"]
    assert reported >= 0.95 * kernel_peak, (reported, kernel_peak)
    assert reported > 320e6


def test_stats_record_the_intrinsics_and_where_they_came_from(sequence, tmp_path, capsys):
    import shutil

    run_named("odometry", sequence, tmp_path / "a", progress=False)
    used = json.loads((tmp_path / "a" / "stats.json").read_text())["intrinsics"]
    assert used["fx"] == pytest.approx(8.0) and used["source"].endswith("camera.json")
    bare = tmp_path / "bare"
    shutil.copytree(sequence, bare)
    (bare / "camera.json").unlink()
    assert main(["run", "--method", "odometry", str(bare), "--out", str(tmp_path / "b")]) == 2
    assert "--intrinsics fx,fy,cx,cy" in capsys.readouterr().err and not (tmp_path / "b").exists()
    assert main(["run", "--method", "odometry", str(bare), "--out", str(tmp_path / "b"), "--intrinsics", "9,9,8,6"]) == 0
    used = json.loads((tmp_path / "b" / "stats.json").read_text())["intrinsics"]
    assert (used["fx"], used["cy"], used["source"]) == (9.0, 6.0, "given (--intrinsics)")
