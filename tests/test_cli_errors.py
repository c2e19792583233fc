"""The CLI turns every expected failure into one line naming the problem, exit code 2, no traceback."""

import json
import os
import subprocess
import sys
import re

import pytest

from helpers.cli_checks import one_line_error
from longslam.cli.main import main



def test_evaluate_json_never_prints_nan_or_infinity(tmp_path, capsys):
    (tmp_path / "gt.txt").write_text("0 0 0 0 0 0 0 1\n0.1 1 0 0 0 0 0 1\n0.2 2 0 0 0 0 0 1\n")
    (tmp_path / "huge.txt").write_text("0 0 0 0 0 0 0 1\n0.1 1e300 0 0 0 0 0 1\n0.2 1e308 0 0 0 0 0 1\n")
    assert main(["evaluate", str(tmp_path / "huge.txt"), str(tmp_path / "gt.txt"), "--json"]) == 2
    assert capsys.readouterr().out == ""
    assert main(["evaluate", str(tmp_path / "huge.txt"), str(tmp_path / "gt.txt"), "--json"]) == 2
    one_line_error(capsys, "huge.txt", "ate", "infinity")
    assert main(["evaluate", str(tmp_path / "gt.txt"), str(tmp_path / "gt.txt"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["ate"] == 0.0


@pytest.fixture(scope="module")
def tiny(tiny_sequence):
    return tiny_sequence


def test_bad_out_for_simulate_is_refused_before_rendering(tmp_path, monkeypatch, capsys):
    from longslam.sim import simulate as recording

    monkeypatch.setattr(recording, "rendered_sequence", lambda *a, **k: pytest.fail("rendered before --out was checked"))
    (tmp_path / "afile").write_text("x")
    for out in (tmp_path / "afile", tmp_path / "afile" / "seq"):
        assert main(["simulate", "--route", "demo", "--out", str(out)]) == 2
        one_line_error(capsys, str(out))


def test_bad_out_for_demo_and_study(tmp_path, capsys):
    (tmp_path / "afile").write_text("x")
    assert main(["demo", "--out", str(tmp_path / "afile")]) == 2
    one_line_error(capsys, "demo folder", "is a file")
    (tmp_path / "r.txt").write_text("20 31.25\n22 31.25\n")
    study = tmp_path / "s.toml"
    study.write_text('routes = ["r.txt"]\nnoise = ["none"]\nmethods = ["odometry"]\nseeds = 1\n')
    assert main(["study", str(study), "--out", str(tmp_path / "afile" / "x")]) == 2
    one_line_error(capsys, "study folder", "is a file")


def test_a_negative_seed_is_refused_before_rendering(tmp_path, monkeypatch, capsys):
    from longslam.sim import simulate as recording

    monkeypatch.setattr(recording, "rendered_sequence", lambda *a, **k: pytest.fail("rendered before the seed was checked"))
    assert main(["simulate", "--route", "demo", "--seed", "-1", "--out", str(tmp_path / "s")]) == 2
    one_line_error(capsys, "seed -1", ">= 0")


@pytest.mark.slow
@pytest.mark.parametrize("second", ["20 31.25", "20.02 31.25"])
def test_a_repeated_waypoint_is_driven_through(tmp_path, capsys, second):
    route = tmp_path / "route.txt"
    route.write_text(f"20 31.25\n{second}\n23 31.25\n23 31.25\n")
    assert main(["world", "--route", str(route), "--out", str(tmp_path / "plan.png")]) == 0
    assert (tmp_path / "plan.png").is_file()


def test_world_out_in_a_missing_folder_or_of_a_wrong_kind(tmp_path, capsys):
    assert main(["world", "--out", str(tmp_path / "nodir" / "x.png")]) == 2
    one_line_error(capsys, "nodir", "does not exist")
    assert main(["world", "--out", str(tmp_path / "x.txt")]) == 2
    one_line_error(capsys, "x.txt", ".png")
    assert main(["world", "--out", str(tmp_path)]) == 2
    one_line_error(capsys, str(tmp_path))


def test_a_folder_as_mesh_says_so(tmp_path, capsys):
    assert main(["world", "--mesh", str(tmp_path), "--out", str(tmp_path / "p.png")]) == 2
    one_line_error(capsys, "is a folder", "mesh file")


def test_debug_shows_the_traceback(tmp_path):
    from longslam.core.errors import InputError

    with pytest.raises(InputError):
        main(["--debug", "world", "--out", str(tmp_path / "x.txt")])
    with pytest.raises(InputError):
        main(["world", "--out", str(tmp_path / "x.txt"), "--debug"])


def _shell(command: str, cwd) -> subprocess.CompletedProcess:

    env = dict(os.environ, LONGSLAM_PY=sys.executable)
    return subprocess.run(["bash", "-c", command], cwd=cwd, env=env, capture_output=True, text=True, timeout=120)


@pytest.mark.slow
def test_evaluate_into_a_closed_pipe_is_quiet(tiny, tmp_path):
    # `true` exits at once, so every write of the scores meets a closed pipe (like `| head -1`
    # after its first line, without the race).
    result = _shell(f'"$LONGSLAM_PY" -m longslam evaluate {tiny / "groundtruth.txt"} {tiny} | true', tmp_path)
    assert "error" not in result.stderr, result.stderr
    for noise in ("Traceback", "BrokenPipe", "Exception ignored"):
        assert noise not in result.stderr, result.stderr


@pytest.mark.slow
@pytest.mark.parametrize("command", ["run", "simulate"])
def test_a_file_size_limit_names_the_file(tiny, tmp_path, command):
    if command == "run":
        args = f"run --method keyframe {tiny} --out {tmp_path / 'out'}"
        limit = 40  # kB: the keyframe's memory.db outgrows it
    else:
        (tmp_path / "route.txt").write_text("20 31.25\n24 31.25\n")
        args = f"simulate --route {tmp_path / 'route.txt'} --out {tmp_path / 'out'} --width 32 --height 24"
        limit = 2
    result = _shell(f'ulimit -f {limit}; LONGSLAM_CACHE={tmp_path / "cache"} "$LONGSLAM_PY" -m longslam {args}', tmp_path)
    assert result.returncode == 2, result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip() and "%" not in line]
    assert "Traceback" not in result.stderr, result.stderr
    assert len(lines) == 1 and "error:" in lines[0] and str(tmp_path) in lines[0], result.stderr
    named = re.search(r"(\S+\.(db|txt|png|json|npz))(:| cannot)", lines[0])  # the file, not only a folder
    assert named and named[1].startswith(str(tmp_path)), lines[0]
    assert not (tmp_path / "out").exists()
