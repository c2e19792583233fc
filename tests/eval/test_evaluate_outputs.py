"""What `longslam evaluate` writes and reads beyond the scores: units in the text and the JSON,
evo_res result files, the APE figures, trajectories from stdin and from ROS bags."""

from __future__ import annotations

import io
import json
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from scipy.spatial.transform import Rotation

from helpers.cli_checks import one_line_error
from longslam.cli.main import main
from longslam.eval.evaluate_output import format_text
from longslam.eval.units import units_of
from longslam.io.trajectory_files import format_tum, write_tum
from longslam.run.score import score_files_full
from longslam.core.trajectory import Trajectory


def _trajectory(rng: np.random.Generator, n: int = 200, noise: float = 0.0, t0: float = 0.0) -> Trajectory:
    """A wavy drive over the floor, optionally with drifting position and heading errors."""
    t = np.arange(n) * 0.1
    yaw = 0.8 * np.sin(0.15 * t)
    step = 0.1 * np.column_stack([np.cos(yaw), np.sin(yaw)])
    xy = np.cumsum(step, axis=0)
    if noise:
        xy = xy + np.cumsum(rng.normal(scale=noise, size=xy.shape), axis=0)
        yaw = yaw + np.cumsum(rng.normal(scale=noise / 2, size=n))
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, :3] = Rotation.from_euler("z", yaw[:, None]).as_matrix()
    poses[:, :2, 3] = xy
    return Trajectory(t0 + t, poses)


@pytest.fixture()
def files(tmp_path) -> tuple[Path, Path, Path]:
    rng = np.random.default_rng(3)
    truth = _trajectory(rng)
    write_tum(tmp_path / "gt.txt", truth)
    write_tum(tmp_path / "est.txt", _trajectory(rng, noise=0.01))
    write_tum(tmp_path / "other.txt", _trajectory(rng, noise=0.03))
    return tmp_path / "gt.txt", tmp_path / "est.txt", tmp_path / "other.txt"


def _json(capsys, *argv: str) -> dict:
    assert main(["evaluate", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


# ----------------------------------------------------------------------------- units and layout


def test_json_has_a_unit_for_every_number(files, capsys):
    gt, est, _ = files
    scores = _json(capsys, str(est), str(gt))
    units = scores.pop("units")
    numeric = {k for k, v in scores.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
    assert numeric <= units.keys(), numeric - units.keys()
    assert (units["ate"], units["e_trans"], units["e_rot"], units["ape_rmse"]) == ("m", "m/m", "deg/m", "m")
    assert (units["rpe_trans"], units["rpe_rot"], units["rpe_delta"], units["path_length"]) == ("m", "deg", "m", "m")
    angle = _json(capsys, str(est), str(gt), "-r", "angle_rad", "-u", "f", "-d", "5")
    assert angle["units"]["ape_rmse"] == angle["units"]["rpe_max"] == "rad"
    assert angle["units"]["rpe_trans"] == "m" and angle["units"]["rpe_delta"] == "frames"
    assert _json(capsys, str(est), str(gt), "-r", "full")["units"]["ape_rmse"] == ""  # a norm of a matrix


def test_text_has_units_rmse_labels_and_one_column(files, capsys):
    gt, est, _ = files
    assert main(["evaluate", str(est), str(gt)]) == 0
    lines = capsys.readouterr().out.splitlines()
    # zero_estimate_steps, the longest name on main, pushed its value out of the column.
    assert len({line.index(": ") for line in lines}) == 1, lines
    text = {line.split(": ")[0].strip(): line.split(": ", 1)[1] for line in lines}
    assert text["ate"].endswith(" m") and text["e_rot"].endswith(" deg/m") and text["e_trans"].endswith(" m/m")
    assert text["rpe_trans (rmse)"].endswith(" m") and text["rpe_rot (rmse)"].endswith(" deg")
    assert "rpe_trans" not in text and text["zero_estimate_steps"] == "0"
    assert text["ape_rmse"].endswith(" m") and text["rpe_delta"] == "1 m"


def test_text_says_why_a_figure_is_undefined():
    scores = {"ate": 0.5, "rpe_trans": None, "rpe_delta": 20.0, "rpe_delta_unit": "d", "e_rot": None}
    text = format_text(scores, min_step=0.05)
    assert "no pair of poses 20.0 deg apart" in text and "no ground-truth step of 0.05 m" in text
    assert units_of(scores)["rpe_delta"] == "deg"


# ----------------------------------------------------------------------------- evo result files


def _evo_result(gt: Path, est: Path, kind: str, **options):
    from evo.core import metrics as evo_metrics, sync
    from evo.main_ape import ape
    from evo.main_rpe import rpe
    from evo.tools import file_interface

    ref, traj = sync.associate_trajectories(file_interface.read_tum_trajectory_file(str(gt)),
                                            file_interface.read_tum_trajectory_file(str(est)))
    if kind == "ape":
        result = ape(ref, traj, evo_metrics.PoseRelation.translation_part, **options)
    else:
        result = rpe(ref, traj, evo_metrics.PoseRelation.translation_part, delta=1.0,
                     delta_unit=evo_metrics.Unit.meters, pairs_from_reference=True, **options)
    result.info.update(ref_name=str(gt), est_name=str(est))
    return result


@pytest.mark.parametrize("kind, option", [("ape", "--save-results"), ("rpe", "--save-rpe-results")])
@pytest.mark.parametrize("align", [[], ["--align", "sim3"]])
def test_saved_results_are_what_evo_saves(files, tmp_path, capsys, kind, option, align):
    from evo.tools import file_interface

    gt, est, _ = files
    out = tmp_path / f"{kind}.zip"
    assert main(["evaluate", str(est), str(gt), option, str(out), *align]) == 0
    ours = file_interface.load_res_file(out, load_trajectories=True)
    theirs = _evo_result(gt, est, kind, **({"align": True, "correct_scale": True} if align else {}))
    assert ours.info == theirs.info  # title, label, names: evo_res groups and labels by them
    assert ours.stats.keys() == theirs.stats.keys()
    for name, value in theirs.stats.items():
        assert ours.stats[name] == pytest.approx(value, rel=1e-6, abs=1e-12), name
    assert ours.np_arrays.keys() == theirs.np_arrays.keys()
    for name, array in theirs.np_arrays.items():
        np.testing.assert_allclose(ours.np_arrays[name], array, rtol=1e-6, atol=1e-9, err_msg=name)
    # load_res_file names a trajectory after its file's stem, as for evo's own files.
    assert set(ours.trajectories) == {gt.name, est.name}
    np.testing.assert_allclose(ours.trajectories[est.name].positions_xyz, theirs.trajectories[str(est)].positions_xyz,
                               atol=1e-8)


def test_a_result_file_is_refused_before_any_work(files, tmp_path, capsys):
    gt, est, _ = files
    assert main(["evaluate", str(est), str(gt), "--save-results", str(tmp_path / "r.json")]) == 2
    one_line_error(capsys, "--save-results", ".zip")
    (tmp_path / "r.zip").write_text("mine")
    assert main(["evaluate", str(est), str(gt), "--save-results", str(tmp_path / "r.zip")]) == 2
    one_line_error(capsys, "exists already", "--overwrite")
    assert (tmp_path / "r.zip").read_text() == "mine"
    assert main(["evaluate", str(est), str(gt), "--save-results", str(tmp_path / "r.zip"), "--overwrite"]) == 0
    assert zipfile.is_zipfile(tmp_path / "r.zip")


@pytest.mark.slow
def test_evo_res_reads_two_saved_results(files, tmp_path, capsys):
    gt, est, other = files
    saved = []
    for name in (est, other):
        saved.append(tmp_path / f"{name.stem}.zip")
        assert main(["evaluate", str(name), str(gt), "--align", "--save-results", str(saved[-1])]) == 0
    scores = [json.loads(line) for line in (_scores(capsys, name, gt) for name in (est, other))]
    evo_res = Path(sys.executable).with_name("evo_res")
    done = subprocess.run([str(evo_res), *map(str, saved), "--no_warnings"], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert "APE w.r.t. translation part (m)" in lines and "(with SE(3) Umeyama alignment)" in lines
    header = next(line for line in lines if "rmse" in line).split()
    assert header[:6] == ["rmse", "mean", "median", "std", "min", "max"]
    for name, score in zip((est, other), scores):
        row = next(line for line in lines if line.startswith(name.name)).split()
        for column, value in zip(header[:6], row[1:7]):
            assert float(value) == pytest.approx(score[f"ape_{column}"], abs=5e-7), (name.name, column)


def _scores(capsys, est: Path, gt: Path) -> str:
    capsys.readouterr()
    assert main(["evaluate", str(est), str(gt), "--align", "--json"]) == 0
    return capsys.readouterr().out


# ----------------------------------------------------------------------------- figures


def test_figures_are_evos_two(files):
    from longslam.viz.evaluation_plots import draw

    gt, est, _ = files
    evaluation = score_files_full(est, gt, align="se3")
    fig = draw(Figure(figsize=(10, 4)), evaluation)
    trajectory, over_time = fig.axes[:2]
    (coloured,) = [c for c in trajectory.collections if isinstance(c, LineCollection)]
    errors = evaluation.ape_errors
    np.testing.assert_allclose(coloured.get_array(), (errors[:-1] + errors[1:]) / 2)
    reference = next(line for line in trajectory.lines if line.get_label() == "reference")
    assert reference.get_linestyle() == "--"
    np.testing.assert_allclose(reference.get_xydata(), evaluation.reference.positions[:, :2])
    levels = {line.get_label().split()[0]: line.get_ydata()[0] for line in over_time.lines[1:]}
    s = evaluation.scores
    assert levels == pytest.approx({"rmse": s["ape_rmse"], "median": s["ape_median"], "mean": s["ape_mean"]})
    (band,) = over_time.patches
    corners = band.get_patch_transform().transform(band.get_path().vertices)[:, 1]
    assert (corners.min(), corners.max()) == pytest.approx((s["ape_mean"] - s["ape_std"], s["ape_mean"] + s["ape_std"]))
    np.testing.assert_allclose(over_time.lines[0].get_ydata(), errors)
    assert "[m]" in over_time.get_ylabel()


@pytest.mark.parametrize("suffix, magic", [(".png", b"\x89PNG"), (".pdf", b"%PDF")])
def test_save_plot_writes_a_file_without_a_display(files, tmp_path, monkeypatch, capsys, suffix, magic):
    monkeypatch.delenv("DISPLAY", raising=False)
    gt, est, _ = files
    out = tmp_path / f"ape{suffix}"
    assert main(["evaluate", str(est), str(gt), "--save-plot", str(out)]) == 0
    assert out.read_bytes()[:4] == magic and out.stat().st_size > 10_000
    assert not list(tmp_path.glob("*partial*"))


def test_plot_options_are_checked(files, tmp_path, capsys):
    gt, est, _ = files
    assert main(["evaluate", str(est), str(gt), "--save-plot", str(tmp_path / "ape.txt")]) == 2
    one_line_error(capsys, "--save-plot", ".png")


def test_plot_without_a_display_is_one_line(files, monkeypatch, capsys):
    import matplotlib

    gt, est, _ = files
    monkeypatch.setattr(matplotlib, "get_backend", lambda: "agg")  # what matplotlib picks with no display
    assert main(["evaluate", str(est), str(gt), "--plot"]) == 2
    assert capsys.readouterr().out == ""  # refused before any work
    assert main(["evaluate", str(est), str(gt), "--plot"]) == 2
    one_line_error(capsys, "--plot needs a display", "--save-plot")


def test_plot_shows_both_panels(files, monkeypatch, capsys):
    import matplotlib
    import matplotlib.pyplot as plt

    gt, est, _ = files
    shown = []
    monkeypatch.setattr(matplotlib, "get_backend", lambda: "TkAgg")
    monkeypatch.setattr(plt, "show", lambda: shown.append([len(plt.figure(n).axes) for n in plt.get_fignums()]))
    try:
        assert main(["evaluate", str(est), str(gt), "-p"]) == 0
    finally:
        plt.close("all")
    assert shown == [[3]]  # one window: trajectory, colour bar, error over time


# ----------------------------------------------------------------------------- stdin and bags


def test_stdin_is_a_trajectory_file(files, monkeypatch, capsys):
    gt, est, _ = files
    from_file = _json(capsys, str(est), str(gt))
    monkeypatch.setattr(sys, "stdin", io.StringIO(est.read_text()))
    from_stdin = _json(capsys, "-", str(gt))
    assert from_stdin == from_file
    monkeypatch.setattr(sys, "stdin", io.StringIO(gt.read_text()))
    assert _json(capsys, str(est), "-") == from_file
    monkeypatch.setattr(sys, "stdin", io.StringIO("1 2 3\n"))
    assert main(["evaluate", "-", str(gt)]) == 2
    one_line_error(capsys, "<stdin>:1", "8")
    assert main(["evaluate", "-", "-"]) == 2
    one_line_error(capsys, "only one", "stdin")


def _write_bag(path: Path, ros: str, topics: dict[str, tuple[str, Trajectory]]) -> None:
    from longslam.io.rosbag.messages import MessageBuilder

    builder = MessageBuilder(ros)
    types = builder.types
    if ros == "ros1":
        from rosbags.rosbag1 import Writer

        writer = Writer(path)
    else:
        from rosbags.rosbag2 import Writer

        writer = Writer(path, version=8)
    writer.open()
    for topic, (msgtype, trajectory) in topics.items():
        connection = writer.add_connection(topic, msgtype, typestore=builder.store)
        for t, pose in zip(trajectory.timestamps, trajectory.poses):
            ns = int(round(t * 1e9))
            qx, qy, qz, qw = Rotation.from_matrix(pose[:3, :3]).as_quat()
            point = types["geometry_msgs/msg/Point"](x=pose[0, 3], y=pose[1, 3], z=pose[2, 3])
            quat = types["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw)
            geometry = types["geometry_msgs/msg/Pose"](position=point, orientation=quat)
            header = builder.header(ns, "map")
            if msgtype.endswith("PoseStamped"):
                message = types[msgtype](header=header, pose=geometry)
            else:  # nav_msgs/Odometry
                covariance = types["geometry_msgs/msg/PoseWithCovariance"](pose=geometry, covariance=np.zeros(36))
                twist = types["geometry_msgs/msg/TwistWithCovariance"](
                    twist=types["geometry_msgs/msg/Twist"](linear=types["geometry_msgs/msg/Vector3"](x=0, y=0, z=0),
                                                           angular=types["geometry_msgs/msg/Vector3"](x=0, y=0, z=0)),
                    covariance=np.zeros(36))
                message = types[msgtype](header=header, child_frame_id="base_link", pose=covariance, twist=twist)
            writer.write(connection, ns, builder.serialize(message, msgtype))
    writer.close()


@pytest.mark.parametrize("ros, name", [("ros1", "poses.bag"), ("ros2", "poses")])
def test_bag_topics_are_trajectories(files, tmp_path, capsys, ros, name):
    pytest.importorskip("rosbags")
    from longslam.io.trajectory_files import read_tum

    gt, est, _ = files
    bag = tmp_path / name
    _write_bag(bag, ros, {"/slam/pose": ("geometry_msgs/msg/PoseStamped", read_tum(est)),
                          "/groundtruth": ("nav_msgs/msg/Odometry", read_tum(gt))})
    from_files = _json(capsys, str(est), str(gt))
    from_bag = _json(capsys, str(bag), str(bag), "--est-topic", "/slam/pose", "--ref-topic", "/groundtruth")
    mixed = _json(capsys, str(bag), str(gt), "--est-topic", "/slam/pose")
    for scores in (from_bag, mixed):
        for key, value in from_files.items():
            if isinstance(value, float):
                assert scores[key] == pytest.approx(value, rel=1e-6, abs=1e-9), key
            else:
                assert scores[key] == value, key
    assert main(["evaluate", str(bag), str(gt)]) == 2
    one_line_error(capsys, "2 pose topics", "/groundtruth", "/slam/pose", "--est-topic")
    assert main(["evaluate", str(bag), str(gt), "--est-topic", "/nope"]) == 2
    one_line_error(capsys, "--est-topic /nope", "no such topic")
    assert main(["evaluate", str(est), str(gt), "--est-topic", "/slam/pose"]) == 2
    one_line_error(capsys, "--est-topic", "not a ROS bag")


def test_tum_text_on_stdin_round_trips_format_tum(files):
    gt, est, _ = files
    from longslam.io.trajectory_files import read_trajectory

    trajectory, fmt = read_trajectory(Path("<stdin>"), text=format_tum(Trajectory(np.arange(3.0), np.tile(np.eye(4), (3, 1, 1)))))
    assert fmt == "tum" and len(trajectory) == 3 and trajectory.source == "<stdin>"


def test_t_offset_is_refused_for_kitti_files(files, tmp_path, capsys):
    from longslam.io.trajectory_files import read_tum, write_kitti

    gt, est, _ = files
    write_kitti(tmp_path / "est.kitti", read_tum(est))
    write_kitti(tmp_path / "gt.kitti", read_tum(gt))
    assert main(["evaluate", str(tmp_path / "est.kitti"), str(tmp_path / "gt.kitti"), "--t-offset", "0.5"]) == 2
    one_line_error(capsys, "--t-offset 0.5", "est.kitti", "by index")
