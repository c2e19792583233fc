"""The `command` method: a program outside longslam run as a method, on the tiny sequences.

The program is a stand-in written here (run with this Python): it reads the associations, writes
the ground truth as a SLAM system would (in a map frame of its own, starting at the identity), and
can start a child that holds memory, print and fail, crash, hang, or report every third frame.
"""

from __future__ import annotations

import json
import os
import shlex
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from helpers.cli_checks import one_line_error
from helpers.tiny_sequences import write_tiny_sequence
from longslam.cli.main import main
from longslam.core.errors import InputError, MethodError
from longslam.core.geometry import anchor, base_to_camera, hold_last, invert, pose_from_xyyaw
from longslam.io.sequence import SequenceReader
from longslam.io.trajectory_files import read_tum
from longslam.run.scored_run import run_named
from longslam.run.score import score
from longslam.slam.catalog import BUILTIN, default_method_names, get_spec

N = 21
CHILD_MB = 150

PROGRAM = textwrap.dedent('''
    """A stand-in SLAM program: reads a TUM folder's associations, writes the ground truth."""
    import argparse, os, subprocess, sys, time
    import numpy as np
    from scipy.spatial.transform import Rotation

    p = argparse.ArgumentParser()
    p.add_argument("sequence"); p.add_argument("associations"); p.add_argument("output")
    p.add_argument("--truth"); p.add_argument("--every", type=int, default=1)
    p.add_argument("--format", default="tum"); p.add_argument("--frame", default="optical")
    p.add_argument("--name", default="CameraTrajectory.txt"); p.add_argument("--child-mb", type=int, default=0)
    p.add_argument("--child-sleep", type=float, default=1.5); p.add_argument("--sleep", type=float, default=0.0)
    p.add_argument("--pids"); p.add_argument("--exit", type=int, default=0); p.add_argument("--signal", type=int)
    p.add_argument("--echo"); p.add_argument("--write", action="store_true"); p.add_argument("--settings")
    a = p.parse_args()
    print("stand-in: reading", a.associations, flush=True)
    child = None
    if a.child_mb or a.pids:
        code = (f"import time; b = bytearray({a.child_mb} << 20)\\n"
                f"for i in range(0, len(b), 4096): b[i] = 1\\n"
                f"time.sleep({a.child_sleep})")
        child = subprocess.Popen([sys.executable, "-c", code])
    if a.pids:
        with open(a.pids, "w") as f:
            f.write(f"{os.getpid()} {child.pid if child else 0}\\n")
    if a.echo:
        with open(os.path.join(a.output, "echo.txt"), "w") as f:
            f.write(a.echo)
    if a.settings:
        with open(a.settings) as src, open(os.path.join(a.output, "settings_seen.yaml"), "w") as dst:
            dst.write(src.read())
    time.sleep(a.sleep)
    if child is not None:
        child.wait()
    if a.signal:
        os.kill(os.getpid(), a.signal)
    if a.exit:
        print("step one done", flush=True)
        print("failing now: no features in frame 7", file=sys.stderr, flush=True)
        sys.exit(a.exit)
    if not a.write:
        sys.exit(0)
    rows = [line.split() for line in open(a.associations) if line.strip()]
    for t, rgb, td, depth in rows:
        assert t == td and os.path.isfile(os.path.join(a.sequence, rgb)) and os.path.isfile(os.path.join(a.sequence, depth))
    truth = np.loadtxt(a.truth, ndmin=2)
    poses = np.tile(np.eye(4), (len(truth), 1, 1))
    poses[:, :3, :3] = Rotation.from_quat(truth[:, 4:8]).as_matrix()
    poses[:, :3, 3] = truth[:, 1:4]
    if a.frame == "robot":  # the camera 1.25 m above the base, looking along its x
        mount = np.eye(4)
        mount[:3, :3] = [[0, 0, 1], [-1, 0, 0], [0, -1, 0]]
        mount[2, 3] = 1.25
        poses = poses @ np.linalg.inv(mount)
    # The program's own map frame: its first pose at the identity, then turned and moved anyhow.
    offset = np.eye(4)
    offset[:3, :3] = Rotation.from_euler("zyx", [0.7, -0.2, 0.4]).as_matrix()
    offset[:3, 3] = [3.0, -2.0, 0.5]
    poses = offset @ np.linalg.inv(poses[0]) @ poses
    quat = Rotation.from_matrix(poses[:, :3, :3]).as_quat()
    with open(os.path.join(a.output, a.name), "w") as f:
        for i, (row, pose, q) in enumerate(zip(rows, poses, quat)):
            if i % a.every:
                continue
            x, y, z = pose[:3, 3]
            if a.format == "kitti":
                f.write(" ".join(f"{v:.9f}" for v in pose[:3, :4].reshape(-1)) + "\\n")
                continue
            t = float(row[0]) * (1e9 if a.format == "euroc" else 1.0)
            f.write(f"{t:.6f} {x:.9f} {y:.9f} {z:.9f} {q[0]:.9f} {q[1]:.9f} {q[2]:.9f} {q[3]:.9f}\\n")
''')


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """21 frames turning 0.6 rad, exact odometry: a program that reports the truth scores 0."""
    return write_tiny_sequence(tmp_path_factory.mktemp("tiny") / "seq", n=N, turn=0.6)


@pytest.fixture(scope="module")
def program(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("program") / "stand_in.py"
    path.write_text(PROGRAM)
    return path


def _command(program: Path, *options: str) -> str:
    words = [sys.executable, str(program), "{sequence}", "{associations}", "{output}", *options]
    return shlex.join(words)


def _truth_option(sequence: Path) -> tuple[str, str]:
    return "--truth", str(sequence / "groundtruth.txt")


@pytest.mark.slow  # starts a program and its child as a run (2.4 s)
def test_a_program_run_as_a_method_is_anchored_and_measured_with_its_child(tiny, program, tmp_path):
    sequence, truth, _ = tiny
    params = {"command": _command(program, *_truth_option(sequence), "--write", "--child-mb", str(CHILD_MB))}
    figures = run_named("command", sequence, tmp_path / "run", params, progress=False)
    run = tmp_path / "run"
    estimate = read_tum(run / "trajectory.txt")
    np.testing.assert_allclose(estimate.poses, truth.poses, atol=1e-5)  # the program's map frame is undone
    assert score(truth, estimate)["ate"] < 1e-5
    method = figures.method_stats
    assert method["coverage"] == 1.0 and method["frames_covered"] == N and method["program_exit_status"] == 0
    assert method["anchor_frame"] == 0 and method["uses_wheel_odometry"] == "the anchor pose only"
    assert str(program) in method["command_line"] and "{" not in method["command_line"]
    # The run's peak is the process tree's: the program's child held 150 MB beside the run's own memory.
    assert figures.peak_rss_bytes >= figures.baseline_rss_bytes + (CHILD_MB - 10) * 2**20
    assert figures.child_processes >= 2 and method["program_max_rss_bytes"] >= (CHILD_MB - 10) * 2**20
    stats = json.loads((run / "stats.json").read_text())
    assert stats["peak_rss_bytes"] == figures.peak_rss_bytes  # written as measured, not the process's own
    # Its console went to the run's console.log; the TUM folder written for it is gone, its files stay.
    assert "stand-in: reading" in (run / "console.log").read_text()
    assert not (run / "sequence").exists() and (run / "program" / "CameraTrajectory.txt").is_file()
    assert not (run / "settings.yaml").exists()  # the command does not use {settings}
    own = read_tum(run / "program_trajectory.txt")
    np.testing.assert_allclose(own.poses, truth.poses, atol=1e-5)
    online = read_tum(run / "online.txt")
    np.testing.assert_allclose(online.poses, np.repeat(truth.poses[:1], N, axis=0), atol=1e-9)


def test_a_sparse_trajectory_holds_its_last_pose_and_reports_its_coverage(tiny, program, tmp_path):
    sequence, truth, _ = tiny
    params = {"command": _command(program, *_truth_option(sequence), "--write", "--every", "3", "--format", "euroc",
                                  "--name", "keyframes.txt"),
              "trajectory": "keyframes.txt", "format": "euroc"}
    figures = run_named("command", sequence, tmp_path / "run", params, progress=False)
    method = figures.method_stats
    assert method["frames_covered"] == 7 and method["coverage"] == pytest.approx(1 / 3)
    assert method["program_poses"] == 7 and method["program_poses_unmatched"] == 0
    estimate = read_tum(tmp_path / "run" / "trajectory.txt")
    assert len(estimate) == N  # a pose a frame: the frames between hold the last reported pose
    held = truth.poses[(np.arange(N) // 3) * 3]
    np.testing.assert_allclose(estimate.poses, held, atol=1e-5)
    own = read_tum(tmp_path / "run" / "program_trajectory.txt")
    np.testing.assert_allclose(own.timestamps, truth.timestamps[::3], atol=1e-9)
    assert score(truth, own)["ate"] < 1e-5  # the reported poses alone score as the truth


def test_a_kitti_file_gives_a_pose_a_frame_in_order(tiny, program, tmp_path):
    sequence, truth, _ = tiny
    params = {"command": _command(program, *_truth_option(sequence), "--write", "--format", "kitti"),
              "format": "kitti"}
    figures = run_named("command", sequence, tmp_path / "run", params, progress=False)
    assert figures.method_stats["coverage"] == 1.0
    np.testing.assert_allclose(read_tum(tmp_path / "run" / "trajectory.txt").poses, truth.poses, atol=1e-5)


def test_robot_frame_poses_become_camera_poses(tiny, program, tmp_path):
    sequence, truth, _ = tiny
    params = {"command": _command(program, *_truth_option(sequence), "--write", "--frame", "robot"), "frame": "robot"}
    figures = run_named("command", sequence, tmp_path / "run", params, progress=False)
    estimate = read_tum(tmp_path / "run" / "trajectory.txt")
    np.testing.assert_allclose(estimate.poses, truth.poses, atol=1e-5)
    assert figures.method_stats["camera_height"] == pytest.approx(1.25)  # the first odometry pose's height


def test_a_program_that_exits_non_zero_fails_the_run_with_its_last_lines(tiny, program, tmp_path):
    sequence, _, _ = tiny
    params = {"command": _command(program, "--exit", "3")}
    with pytest.raises(MethodError) as caught:
        run_named("command", sequence, tmp_path / "run", params, progress=False)
    message = str(caught.value)
    assert "exit status 3" in message and "failing now: no features in frame 7" in message and "\n" not in message
    assert not (tmp_path / "run").exists()  # a failed run leaves no run folder


def test_a_program_killed_by_a_signal_is_named_by_it(tiny, program, tmp_path):
    sequence, _, _ = tiny
    params = {"command": _command(program, "--signal", str(int(signal.SIGTERM)))}
    with pytest.raises(MethodError, match="killed by SIGTERM"):
        run_named("command", sequence, tmp_path / "run", params, progress=False)


def _gone(pid: int, within: float = 5.0) -> bool:
    deadline = time.monotonic() + within
    while time.monotonic() < deadline:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except (FileNotFoundError, ProcessLookupError):
            return True
        if state in ("Z", "X"):  # ended; its parent (init, for the orphaned child) reaps it
            return True
        time.sleep(0.05)
    return False


def test_a_timeout_kills_the_program_and_its_children(tiny, program, tmp_path):
    sequence, _, _ = tiny
    pids = tmp_path / "pids.txt"
    params = {"command": _command(program, "--pids", str(pids), "--child-sleep", "60", "--sleep", "60"),
              "timeout": 1.5}
    t0 = time.monotonic()
    with pytest.raises(MethodError, match="timeout of 1.5 s") as caught:
        run_named("command", sequence, tmp_path / "run", params, progress=False)
    assert time.monotonic() - t0 < 15
    assert "stand-in: reading" in str(caught.value)
    leader, child = (int(v) for v in pids.read_text().split())
    assert _gone(leader) and _gone(child)
    assert not (tmp_path / "run").exists()


def test_a_program_that_writes_no_trajectory_fails_clearly(tiny, program, tmp_path):
    sequence, _, _ = tiny
    with pytest.raises(MethodError, match=r"status 0 but wrote no trajectory .*CameraTrajectory.txt"):
        run_named("command", sequence, tmp_path / "run", {"command": _command(program)}, progress=False)


def test_the_settings_file_and_the_numbers_hold_the_camera(tiny, program, tmp_path):
    sequence, _, _ = tiny
    command = _command(program, *_truth_option(sequence), "--write", "--echo", "{fx:.3f} {cx} {width}x{height} {depth_scale}",
                       "--settings", "{settings}")
    params = {"command": command, "keep_sequence": True}
    run_named("command", sequence, tmp_path / "run", params, progress=False)
    run = tmp_path / "run"
    assert (run / "program" / "echo.txt").read_text() == "8.000 8.0 16x12 5000"
    assert (run / "program" / "settings_seen.yaml").read_text() == (run / "settings.yaml").read_text()
    settings = cv2.FileStorage(str(run / "settings.yaml"), cv2.FILE_STORAGE_READ)
    assert settings.getNode("File.version").string() == "1.0" and settings.getNode("Camera.type").string() == "PinHole"
    for key, value in (("fx", 8.0), ("fy", 8.0), ("cx", 8.0), ("cy", 6.0)):
        assert settings.getNode(f"Camera1.{key}").real() == pytest.approx(value)
        assert settings.getNode(f"Camera.{key}").real() == pytest.approx(value)
    assert (settings.getNode("Camera.width").real(), settings.getNode("Camera.height").real()) == (16, 12)
    assert settings.getNode("Camera.fps").real() == 10 and settings.getNode("RGBD.DepthMapFactor").real() == 5000
    assert settings.getNode("Stereo.ThDepth").real() == 40 and settings.getNode("Camera.bf").real() == pytest.approx(8 * 0.07732)
    # The TUM folder the program read, kept: the frames as the method saw them, with odometry, no ground truth.
    written, original = SequenceReader(run / "sequence"), SequenceReader(sequence)
    assert len(written) == N and not (run / "sequence" / "groundtruth.txt").exists()
    np.testing.assert_allclose(written.odometry.poses, original.odometry.poses, atol=1e-6)
    for a, b in zip(written, original):
        assert np.array_equal(a.rgb, b.rgb) and np.allclose(a.depth, b.depth, atol=1e-3)
    lines = (run / "sequence" / "associations.txt").read_text().splitlines()
    t = lines[0].split()[0]
    assert len(lines) == N and lines[0] == f"{t} rgb/{t}.png {t} depth/{t}.png"


def test_parameters_are_checked_before_any_frame(tiny, tmp_path, capsys):
    spec = get_spec("command")
    with pytest.raises(InputError, match=r"unknown placeholder \{nope\}") as caught:
        spec.config({"command": "prog {sequence} {nope}"})
    assert "\n" not in str(caught.value) and "{output}" in str(caught.value)  # the valid ones are listed
    for params, needle in (({"command": "prog {fx:zz}"}, "cannot be filled"), ({"command": "prog 'a"}, "quotation"),
                           ({"format": "g2o"}, "format must be one of tum, euroc, kitti, got 'g2o'"),
                           ({"frame": "base"}, "frame must be one of optical, robot, got 'base'"),
                           ({"trajectory": "../x.txt"}, "relative to {output}"), ({"timeout": 0}, "timeout must be in (0, ")):
        with pytest.raises(InputError, match=needle.replace("(", r"\(").replace("{", r"\{")):
            spec.config(params)
    sequence = tiny[0]
    # From the command line: one line, exit status 2, nothing written.
    assert main(["run", "--method", "command", str(sequence), "--out", str(tmp_path / "a"),
                 "--param", "command=prog {sequence} {nope}"]) == 2
    one_line_error(capsys, "unknown placeholder {nope}")
    assert main(["run", "--method", "command", str(sequence), "--out", str(tmp_path / "b")]) == 2
    one_line_error(capsys, "needs the program to run")
    assert main(["run", "--method", "command", str(sequence), "--out", str(tmp_path / "c"),
                 "--param", "command=no-such-slam-program {sequence}"]) == 2
    one_line_error(capsys, "'no-such-slam-program' is not on PATH")
    assert not any(tmp_path.iterdir())


def test_a_command_with_spaces_runs_from_the_command_line(tiny, program, tmp_path, capsys):
    sequence, truth, _ = tiny
    out = tmp_path / "run"
    command = _command(program, *_truth_option(sequence), "--write", "--name", "poses.txt")
    assert main(["run", "--method", "command", str(sequence), "--out", str(out), "--param", f"command={command}",
                 "--param", "trajectory=poses.txt"]) == 0
    assert score(truth, read_tum(out / "trajectory.txt"))["ate"] < 1e-5
    config = (out / "config.toml").read_text()
    assert 'trajectory = "poses.txt"' in config and str(program) in config  # the run can be repeated from its folder


@pytest.mark.slow
def test_the_installed_command_runs_a_program(tiny, program, tmp_path):
    """`longslam run --method command SEQ --param command="prog {sequence} {output}" ...` in a shell."""
    sequence, truth, _ = tiny
    out = tmp_path / "run"
    command = _command(program, *_truth_option(sequence), "--write")
    line = (f"{shlex.quote(sys.executable)} -m longslam run --method command {shlex.quote(str(sequence))} "
            f"--out {shlex.quote(str(out))} --param command={shlex.quote(command)} "
            "--param trajectory=CameraTrajectory.txt")
    done = subprocess.run(line, shell=True, capture_output=True, text=True, env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)})
    assert done.returncode == 0, done.stderr
    assert score(truth, read_tum(out / "trajectory.txt"))["ate"] < 1e-5


def test_every_method_means_those_that_run_without_parameters(tmp_path):
    from longslam.study.config import StudyConfigError, check_method_params, load_study

    assert "command" in BUILTIN and "command" not in default_method_names()
    base = 'world = "university"\nroutes = ["demo"]\nnoise = ["small"]\nseeds = 1\n'
    (tmp_path / "all.toml").write_text(base + 'methods = "all"\n')
    assert "command" not in [m.method for m in load_study(tmp_path / "all.toml").methods]
    (tmp_path / "given.toml").write_text(base + 'methods = "all"\n[params.command]\ncommand = "true {sequence}"\n')
    given = load_study(tmp_path / "given.toml")
    assert "command" in [m.method for m in given.methods]
    check_method_params(given)
    (tmp_path / "named.toml").write_text(base + 'methods = ["command"]\n')
    with pytest.raises(StudyConfigError, match="needs the parameter command"):
        check_method_params(load_study(tmp_path / "named.toml"))


def test_anchoring_places_the_first_pose_and_holds_between():
    rng = np.random.default_rng(3)
    own = np.array([pose_from_xyyaw(v, z) for v, z in zip(rng.normal(size=(5, 3)), rng.normal(size=5))])
    world_first = pose_from_xyyaw([1.0, 2.0, 0.3], 1.25) @ base_to_camera(1.25)
    placed = anchor(own, world_first)
    np.testing.assert_allclose(placed[0], world_first, atol=1e-12)
    for i in range(5):  # relative poses are the program's own
        np.testing.assert_allclose(invert(placed[0]) @ placed[i], invert(own[0]) @ own[i], atol=1e-12)
    start = np.eye(4)
    held = hold_last(7, np.array([2, 5]), placed[:2], start)
    assert [int(np.argmin([np.abs(h - c).max() for c in (start, placed[0], placed[1])])) for h in held] == [0, 0, 1, 1, 1, 2, 2]
