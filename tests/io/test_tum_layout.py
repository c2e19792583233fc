"""A TUM RGB-D download unpacked as it is (rgbd_dataset_freiburg1_xyz/ with its three-line '#'
headers, 100 Hz ground truth with stamps of its own, 16-bit depth scaled by 5000, no camera.json
and no odometry.txt) runs end to end with `longslam run` and `longslam evaluate`."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from longslam.cli.main import main
from longslam.eval.evaluation import evaluate
from longslam.core.geometry import planar_poses
from longslam.core.trajectory import Trajectory

pytestmark = pytest.mark.slow  # runs the methods on TUM-layout sequences

T0 = 1305031102.175304  # the first colour stamp of the real freiburg1_xyz


def write_tum_download(folder: Path, n: int = 20, speed: float = 0.6) -> None:
    """`folder` as TUM ships it: rgb/ and depth/ PNGs named by their stamps, rgb.txt, depth.txt,
    groundtruth.txt (4-decimal stamps at 100 Hz from 3.5 s before the first image) and
    accelerometer.txt, each with its three-line header. Colour at 30 Hz with jitter, each depth
    image 5-15 ms after its colour image; the camera moves `speed` m/s."""
    rng = np.random.default_rng(1)
    (folder / "rgb").mkdir(parents=True)
    (folder / "depth").mkdir()
    bag = f"# file: '{folder.name}.bag'"
    rgb_t = T0 + np.arange(n) / 30.0 + rng.uniform(-0.002, 0.002, n)
    depth_t = rgb_t + rng.uniform(0.005, 0.015, n)
    rgb_lines = ["# color images", bag, "# timestamp filename"]
    depth_lines = ["# depth maps", bag, "# timestamp filename"]
    texture = rng.integers(0, 256, (60, 80, 3), dtype=np.uint8)
    for k, (tr, td) in enumerate(zip(rgb_t, depth_t)):
        colour = cv2.resize(np.roll(texture, k, axis=1), (640, 480), interpolation=cv2.INTER_NEAREST)
        depth = np.full((480, 640), 2 * 5000, np.uint16)  # a wall 2 m ahead
        depth[:40] = 0  # no return
        cv2.imwrite(str(folder / "rgb" / f"{tr:.6f}.png"), colour)
        cv2.imwrite(str(folder / "depth" / f"{td:.6f}.png"), depth)
        rgb_lines.append(f"{tr:.6f} rgb/{tr:.6f}.png")
        depth_lines.append(f"{td:.6f} depth/{td:.6f}.png")
    (folder / "rgb.txt").write_text("\n".join(rgb_lines) + "\n")
    (folder / "depth.txt").write_text("\n".join(depth_lines) + "\n")
    truth = ["# ground truth trajectory", bag, "# timestamp tx ty tz qx qy qz qw"]
    for t in np.arange(T0 - 3.5, rgb_t[-1] + 1.0, 0.01):
        s = t - T0
        q = Rotation.from_euler("xyz", [-np.pi / 2, 0.0, -np.pi / 2 + 0.1 * s]).as_quat()
        truth.append(f"{t:.4f} {1.3563 + speed * s:.4f} 0.6305 1.6380 {q[0]:.4f} {q[1]:.4f} {q[2]:.4f} {q[3]:.4f}")
    (folder / "groundtruth.txt").write_text("\n".join(truth) + "\n")
    (folder / "accelerometer.txt").write_text(f"# accelerometer data\n{bag}\n# timestamp ax ay az\n{T0:.6f} -0.0539 -9.6456 -1.1010\n")


def test_a_tum_download_runs_and_evaluates(tmp_path, capsys):
    folder = tmp_path / "rgbd_dataset_freiburg1_xyz"
    write_tum_download(folder)
    assert main(["run", "--method", "keyframe", str(folder), "--out", str(tmp_path / "run")]) == 0
    stats = json.loads((tmp_path / "run" / "stats.json").read_text())
    assert stats["intrinsics"]["fx"] == 517.3 and "freiburg1" in stats["intrinsics"]["source"]
    assert stats["frames"] == 20
    assert "none" in stats["method_stats"]["frontend"]["odometry_source"]  # no odometry.txt: said so
    capsys.readouterr()
    assert main(["evaluate", str(tmp_path / "run"), str(folder), "--json"]) == 0
    scores = json.loads(capsys.readouterr().out)
    assert scores["matched_poses"] == 20  # every frame found its 100 Hz ground-truth pose
    assert np.isfinite(scores["ate"]) and np.isfinite(scores["e_trans"]) and scores["used_steps"] == 19
    assert scores["rpe_trans"] is None and scores["rpe_pairs"] == 0  # 0.4 m of path: no 1 m segment
    # the odometry method needs odometry, which a TUM download has not
    assert main(["run", "--method", "odometry", str(folder), "--out", str(tmp_path / "odo")]) == 2
    assert "needs a sequence with odometry.txt" in capsys.readouterr().err


def test_a_slow_sequence_has_no_e_trans_but_every_other_metric(capsys, tmp_path):
    # freiburg2_xyz moves about 2 mm a frame at 30 Hz: no step reaches the 1 cm of min_step
    n = 900  # 30 s, 1.8 m
    xyyaw = np.column_stack([0.002 * np.arange(n), np.zeros(n), np.zeros(n)])
    truth = Trajectory(np.arange(n) / 30.0, planar_poses(xyyaw))
    estimate = Trajectory(truth.timestamps, planar_poses(xyyaw * [1.1, 1.0, 1.0]))
    scores = evaluate(truth, estimate)
    assert scores["e_trans"] is None and scores["e_rot"] is None and scores["skipped_steps"] == n - 1
    assert scores["ate"] > 0 and scores["rpe_trans"] > 0 and scores["rpe_pairs"] == 1
    finer = evaluate(truth, estimate, min_step=0.001)
    assert finer["e_trans"] == pytest.approx(0.1)
