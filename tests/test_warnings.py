"""Warnings for what runs but is likely not what the user meant: an option that has no effect,
poses of another frame, a shorter sequence, a wait or a planning that would otherwise be silent.
Each was silent before its fix."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from helpers.cli_checks import one_line_error
from helpers.tiny_sequences import write_tiny_sequence
from longslam.cli.main import main


@pytest.fixture()
def seq(tmp_path) -> Path:
    return write_tiny_sequence(tmp_path / "seq", n=30, turn=1.0)[0]


def _warnings(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("warning:")]


def test_n_to_align_without_align_is_warned_of(tmp_path, capsys):
    from longslam.io.trajectory_files import write_tum
    from longslam.core.trajectory import Trajectory

    angle = np.linspace(0.0, 3.0, 30)
    poses = np.tile(np.eye(4), (30, 1, 1))
    poses[:, 0, 3], poses[:, 1, 3] = np.cos(angle), np.sin(angle)  # an arc, which an alignment can fit
    files = [str(tmp_path / "est.txt"), str(tmp_path / "gt.txt")]
    for file, shift in zip(files, (0.1, 0.0)):
        moved = poses.copy()
        moved[:, 0, 3] += shift
        write_tum(Path(file), Trajectory(0.1 * np.arange(30), moved))
    assert main(["evaluate", *files, "--n-to-align", "5"]) == 0
    assert _warnings(capsys.readouterr().err) == ["warning: --n-to-align 5 has no effect without --align (or -a, -s)"]
    for align in (["--align"], ["-a"], ["-s"]):
        assert main(["evaluate", *files, "--n-to-align", "5", *align]) == 0
        assert _warnings(capsys.readouterr().err) == []


def _odometry_bag(path: Path, trajectory, child: str) -> None:
    """A ROS 1 bag of one nav_msgs/Odometry topic, /odom, whose poses are of `child`."""
    from rosbags.rosbag1 import Writer
    from scipy.spatial.transform import Rotation

    from longslam.io.rosbag.messages import MessageBuilder

    builder = MessageBuilder("ros1")
    types, msgtype = builder.types, "nav_msgs/msg/Odometry"
    writer = Writer(path)
    writer.open()
    connection = writer.add_connection("/odom", msgtype, typestore=builder.store)
    zero = types["geometry_msgs/msg/Vector3"](x=0, y=0, z=0)
    for t, pose in zip(trajectory.timestamps, trajectory.poses):
        ns = int(round(t * 1e9))
        qx, qy, qz, qw = Rotation.from_matrix(pose[:3, :3]).as_quat()
        geometry = types["geometry_msgs/msg/Pose"](
            position=types["geometry_msgs/msg/Point"](x=pose[0, 3], y=pose[1, 3], z=pose[2, 3]),
            orientation=types["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw))
        message = types[msgtype](
            header=builder.header(ns, "odom"), child_frame_id=child,
            pose=types["geometry_msgs/msg/PoseWithCovariance"](pose=geometry, covariance=np.zeros(36)),
            twist=types["geometry_msgs/msg/TwistWithCovariance"](
                twist=types["geometry_msgs/msg/Twist"](linear=zero, angular=zero), covariance=np.zeros(36)))
        writer.write(connection, ns, builder.serialize(message, msgtype))
    writer.close()


@pytest.mark.parametrize("child, warned", [("base_link", True), ("camera_color_optical_frame", False)])
def test_a_bags_base_link_scored_against_camera_poses_is_warned_of(tmp_path, capsys, child, warned):
    pytest.importorskip("rosbags")
    path, truth, odometry = write_tiny_sequence(tmp_path / "seq", n=30)
    bag = tmp_path / "odom.bag"
    _odometry_bag(bag, odometry, child)
    assert main(["evaluate", str(bag), str(path)]) == 0
    found = _warnings(capsys.readouterr().err)
    if warned:
        assert len(found) == 1 and "/odom in" in found[0] and "poses of base_link" in found[0] \
            and "groundtruth.txt of camera poses" in found[0], found
    else:
        assert found == []


def test_diagnose_against_a_shorter_sequence_is_warned_of(tmp_path, capsys):
    long_seq = write_tiny_sequence(tmp_path / "long", n=40)[0]
    short = write_tiny_sequence(tmp_path / "short", n=10)[0]
    run = tmp_path / "run"
    assert main(["run", "--method", "odometry", str(long_seq), "--out", str(run)]) == 0
    capsys.readouterr()
    assert main(["diagnose", str(run), str(short)]) == 0
    found = _warnings(capsys.readouterr().err)
    assert any("only 10 of 40 poses" in w and "cover that part only" in w for w in found), found
    assert main(["diagnose", str(run), str(long_seq)]) == 0
    assert _warnings(capsys.readouterr().err) == []


def test_waiting_for_another_build_of_the_default_vocabulary_says_so(vocabulary_cache, monkeypatch, caplog):
    import fcntl
    import threading

    from longslam.vocabulary import default

    monkeypatch.setattr(default, "WAIT_NOTE_S", 0.2)
    path = default.default_vocabulary_path()
    path.parent.mkdir(parents=True)
    with open(path.with_suffix(".lock"), "w") as held:
        fcntl.flock(held, fcntl.LOCK_EX)  # another process's build
        waiter = threading.Thread(target=default.default_vocabulary, kwargs={"progress": False})
        with caplog.at_level("WARNING", logger="longslam"):
            waiter.start()
            waiter.join(1.0)
            assert waiter.is_alive()
            fcntl.flock(held, fcntl.LOCK_UN)
            waiter.join(10.0)
    notes = [r.getMessage() for r in caplog.records]
    assert any("another process is building the default vocabulary" in n and str(path) in n for n in notes), notes
    assert any("still waiting for the default vocabulary" in n for n in notes), notes
    assert vocabulary_cache == [path]


def test_a_long_route_plans_each_leg_once_and_says_it_takes_a_while(monkeypatch, caplog):
    from longslam.sim import drive
    from longslam.sim.navigation import NavigationGrid
    from longslam.sim.routes import get_route
    from longslam.world.reference import load_world

    planned = []
    plan = NavigationGrid.shortest_path
    monkeypatch.setattr(NavigationGrid, "shortest_path", lambda self, a, b: planned.append((a, b)) or plan(self, a, b))
    monkeypatch.setattr(drive, "LONG_ROUTE_LEGS", 10)
    route = get_route("demo-x3")  # demo's legs 3 times over, joined: 20 legs; demo-x1000 was silent for 8 minutes
    with caplog.at_level("WARNING", logger="longslam"):
        driven = drive.drive_route(load_world(route.world), route)
    assert len(planned) == len(set(map(str, planned))) <= 7
    assert len(driven.waypoint_frames) == len(route.waypoints) == 21
    assert [r.getMessage() for r in caplog.records] == ["note: route demo-x3: planning and driving its 20 legs takes a while"]


def test_a_one_frame_run_has_no_real_time_factor(tmp_path, capsys):
    import json

    seq = write_tiny_sequence(tmp_path / "seq", n=1)[0]
    assert main(["run", "--method", "odometry", str(seq), "--out", str(tmp_path / "run")]) == 0
    out = capsys.readouterr().out
    assert "real-time factor unknown (the sequence spans no time)" in out and "slower than real time" not in out
    assert json.loads((tmp_path / "run" / "stats.json").read_text())["real_time_factor"] is None


def _count_with_a_bar() -> int:
    from longslam.core.progress import bar

    return sum(1 for _ in bar(range(50), desc="counting", mininterval=0))


def test_demo_draws_no_bars_when_stderr_is_not_a_terminal(tmp_path, capfd, monkeypatch):
    from longslam.cli import demo
    from longslam.core import progress
    from longslam.run.isolate import run_isolated

    given = {}
    monkeypatch.setattr(demo, "run_demo", lambda *a, **k: given.update(k) or ([], tmp_path / "trajectories.png"))
    monkeypatch.setattr(demo, "format_table", lambda rows: "")
    assert main(["demo", "--out", str(tmp_path / "demo")]) == 0
    assert given["progress"] is False  # stderr is pytest's capture, not a terminal
    # a run of the demo is in a process of its own, which must not draw them either
    assert not progress.enabled()
    assert run_isolated(_count_with_a_bar) == 50
    assert "counting" not in capfd.readouterr().err


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


def test_units_mm_on_a_metre_mesh_says_so(tmp_path, capsys):
    pytest.importorskip("trimesh")
    from longslam.world.wing_building import write_building

    ply, _ = write_building(tmp_path / "b")
    assert main(["world", "--world", str(ply), "--units", "mm", "--out", str(tmp_path / "p.png")]) == 2
    line = one_line_error(capsys, "too small to be a building", "leave out --units")
    assert "--floor" not in line


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
