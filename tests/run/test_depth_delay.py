"""`run --depth-delay`: depth out of step with its colour by a known time, moved back in step by the
odometry before the method sees it; the simulator's `depth-offset` perturbation undone on a turn."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from longslam.cli.main import main
from longslam.core.errors import InputError
from longslam.core.frame import Frame, Intrinsics
from longslam.core.trajectory import Trajectory
from longslam.run.depth_delay import check_depth_delay, frames_in_step
from longslam.sim.perturbations import get_perturbation
from longslam.sim.perturbations.stream import frame_context
from longslam.sim.sensors.stream import camera_motions

from helpers.cli_checks import one_line_error

K = Intrinsics.from_fov(64, 48, 90.0)  # fx = 32 px
RATE = 10.0


def _turning_poses(n: int, deg_per_s: float, speed: float) -> np.ndarray:
    """Camera-in-world poses (OpenCV axes, y down) of a camera driving forward while turning left."""
    poses = []
    for i in range(n):
        yaw = math.radians(deg_per_s) * i / RATE
        c, s = math.cos(yaw), math.sin(yaw)
        pose = np.eye(4)
        pose[:3, :3] = np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])  # about -y: to the left
        pose[:3, 3] = [-speed * i / RATE * s, 0.0, speed * i / RATE * c] if deg_per_s == 0 else [0.0, 0.0, 0.0]
        poses.append(pose)
    return np.array(poses)


def _box_depth() -> np.ndarray:
    depth = np.full((48, 64), 3.0, np.float32)
    depth[:, 32:] = 1.5  # a near box on the right half: its edge shows where the depth was seen from
    return depth


def _lagged_frames(seconds: float, poses: np.ndarray) -> tuple[list[Frame], np.ndarray]:
    """Frames whose depth is the simulator's `depth-offset=seconds` of one box scene, and that scene."""
    stamps = np.arange(len(poses)) / RATE
    motions = camera_motions(Trajectory(stamps, poses))
    offset = get_perturbation("depth-offset", seconds)
    clean = _box_depth()
    frames = []
    for i, t in enumerate(stamps):
        frame = Frame(i, float(t), np.zeros((48, 64, 3), np.uint8), clean, poses[i], K)
        context = frame_context(frame, stamps, motions, 0)
        _, depth = offset.perturb(frame.rgb, clean, context, np.random.default_rng(0))
        frames.append(Frame(i, float(t), frame.rgb, depth, poses[i], K))
    return frames, clean


def _edge(depth: np.ndarray) -> int:
    return int(np.argmax((depth[24] > 0) & (depth[24] < 2.0)))


@pytest.mark.parametrize("seconds", [0.1, 0.05, -0.1])
def test_a_turns_depth_offset_is_put_back_in_step(seconds):
    poses = _turning_poses(6, 90.0, 0.0)  # turning on the spot at 90 deg/s: 9 degrees in 0.1 s
    frames, clean = _lagged_frames(seconds, poses)
    inner = frames[2]  # a step on both sides
    assert abs(_edge(inner.depth) - _edge(clean)) >= 2  # the offset moved the box's edge
    moved = {f.index: f for f in frames_in_step(frames, seconds, "test")}
    assert sorted(moved) == list(range(6))  # every frame, in order, a lead's last one too
    back = moved[2].depth
    assert _edge(back) == _edge(clean)
    # What is left is the two warps' rounding to whole pixels, far under the offset's own error.
    seen, seen_before = (back > 0) & (clean > 0), (inner.depth > 0) & (clean > 0)
    left = np.median(np.abs(back[seen] - clean[seen]))
    before = np.median(np.abs(inner.depth[seen_before] - clean[seen_before]))
    assert seen.mean() > 0.8 and left < 5e-3 and left < before / 5, (left, before)


def test_driving_ahead_the_wall_comes_back_to_its_distance():
    poses = _turning_poses(4, 0.0, 1.5)  # 1.5 m/s straight ahead
    wall = np.full((48, 64), 4.0, np.float32)
    frames = [Frame(i, i / RATE, np.zeros((48, 64, 3), np.uint8), wall + 0.15, poses[i], K) for i in range(4)]
    back = list(frames_in_step(frames, 0.1, "test"))
    assert np.median(back[2].depth[back[2].depth > 0]) == pytest.approx(4.0, abs=1e-3)
    assert np.array_equal(back[0].depth, wall + 0.15)  # the first frame has no step before it


def test_the_depth_is_moved_only_when_read():
    poses = _turning_poses(3, 90.0, 0.0)
    reads = []

    def depth() -> np.ndarray:
        reads.append(1)
        return _box_depth()

    frames = [Frame(i, i / RATE, np.zeros((48, 64, 3), np.uint8), depth, poses[i], K) for i in range(3)]
    out = list(frames_in_step(frames, 0.1, "test"))
    assert reads == []
    out[1].depth
    assert reads == [1]


def test_a_frame_without_odometry_is_named():
    frames = [Frame(i, i / RATE, np.zeros((48, 64, 3), np.uint8), _box_depth(), None, K) for i in range(3)]
    with pytest.raises(InputError, match=r"^seq: frame 0 has no odometry, which a depth delay needs$"):
        list(frames_in_step(frames, 0.1, "seq"))


@pytest.mark.parametrize("bad", [math.nan, math.inf, 0.7, -0.51])
def test_a_delay_out_of_range_is_refused(bad):
    with pytest.raises(InputError) as err:
        check_depth_delay(bad)
    assert "--depth-delay" in str(err.value) and "between -0.5 and 0.5" in str(err.value)
    assert "\n" not in str(err.value)


def test_cli_run_records_the_delay_and_refuses_a_bad_one(tiny_sequence, tmp_path, capsys):
    out = tmp_path / "run"
    main(["run", "--method", "odometry", str(tiny_sequence), "--out", str(out), "--depth-delay", "0.05", "--no-progress"])
    assert json.loads((out / "stats.json").read_text())["depth_delay_s"] == 0.05
    capsys.readouterr()
    bad = tmp_path / "bad"
    assert main(["run", "--method", "odometry", str(tiny_sequence), "--out", str(bad), "--depth-delay", "2"]) != 0
    one_line_error(capsys, "--depth-delay: 2.0 is not a delay", "between -0.5 and 0.5")
    assert not bad.exists()
