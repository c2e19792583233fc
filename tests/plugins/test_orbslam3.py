"""The ORB-SLAM3 plugin (plugins/longslam-orbslam3) in longslam's harness: it registers, runs on a
rendered sequence, lands in longslam's world frame, and survives frames it cannot track.

The plugin is a separate, GPL distribution: these tests reach it only as users do (the catalogue,
the CLI); its pure parts (map anchoring, settings, console counts) are checked directly. Skipped
where the plugin or pyorbslam3's system libraries are not installed.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from longslam.core.frame import Intrinsics
from longslam.core.geometry import camera_poses_from_planar
from longslam.io.trajectory_files import read_tum
from longslam.sim.camera import CameraSettings
from longslam.sim.routes import Route
from longslam.slam import catalog
from longslam.core.trajectory import Trajectory

plugin = pytest.importorskip("longslam_orbslam3", reason="the orbslam3 plugin is not installed")

from longslam_orbslam3.anchoring import MapAnchors, final_poses  # noqa: E402
from longslam_orbslam3.config import OrbSlam3Config, close_depth_factor  # noqa: E402
from longslam_orbslam3.console_log import count_markers  # noqa: E402
from longslam_orbslam3.settings_file import fps_from_stamps, settings_yaml  # noqa: E402

pytestmark = pytest.mark.slow  # runs ORB-SLAM3, some of it in processes


def _pose(x: float, y: float = 0.0, yaw: float = 0.0) -> np.ndarray:
    return camera_poses_from_planar(np.array([[x, y, yaw]]), 1.25)[0]


def _orb_forward(z: float) -> np.ndarray:
    """ORB-SLAM3 camera-in-map: the camera z metres ahead of the map's first frame."""
    pose = np.eye(4)
    pose[2, 3] = z
    return pose


# -- pure parts -------------------------------------------------------------------------------

def test_first_map_starts_at_the_start_pose_and_follows_orbslam3():
    start = _pose(10.0, 31.25)
    anchors = MapAnchors(start)
    assert np.allclose(anchors.update("OK", np.eye(4)), start)
    moved = anchors.update("OK", _orb_forward(0.5))
    # The optical z axis is the robot's forward direction (+x in the world at yaw 0).
    assert np.allclose(moved[:3, 3], [10.5, 31.25, 1.25])


def test_untracked_frames_hold_the_last_pose_and_a_new_map_continues_from_it():
    anchors = MapAnchors(_pose(0.0))
    anchors.update("OK", np.eye(4))
    anchors.update("OK", _orb_forward(1.0))
    held = anchors.update("RECENTLY_LOST", np.eye(4))  # ORB-SLAM3's identity in RECENTLY_LOST is ignored
    assert np.allclose(held[:3, 3], [1.0, 0.0, 1.25])
    anchors.update("LOST", None)
    restarted = anchors.update("OK", np.eye(4))  # a new map begins at its own identity
    assert np.allclose(restarted[:3, 3], [1.0, 0.0, 1.25])
    assert np.allclose(anchors.update("OK", _orb_forward(0.5))[:3, 3], [1.5, 0.0, 1.25])
    assert len(anchors.anchors) == 2 and anchors.frames_untracked == 2
    assert anchors.segment_of_frame == [0, 0, -1, -1, 1, 1]
    assert anchors.states == {"OK": 4, "RECENTLY_LOST": 1, "LOST": 1}


def test_a_frame_never_tracked_holds_the_start():
    anchors = MapAnchors(_pose(3.0))
    assert np.allclose(anchors.update("NOT_INITIALIZED", None), _pose(3.0))
    assert anchors.segment_of_frame == [-1]


def test_final_poses_take_the_saved_map_in_its_segment_and_online_poses_elsewhere():
    anchors = MapAnchors(_pose(0.0))
    online = [anchors.update("OK", np.eye(4)), anchors.update("OK", _orb_forward(1.0)),
              anchors.update("LOST", None), anchors.update("OK", np.eye(4)), anchors.update("OK", _orb_forward(1.0))]
    stamps = np.arange(5) * 0.1
    # ORB-SLAM3 saved only its largest map, the second: frames 3 and 4, in that map's frame, with
    # frame 4 corrected by a loop closure to 0.8 m ahead.
    saved = np.stack([np.eye(4), _orb_forward(0.8)])
    poses, taken = final_poses(np.array(online), stamps, anchors, stamps[[3, 4]] + 1e-6, saved)
    assert taken == 2
    assert np.allclose(poses[:3], np.array(online)[:3])
    assert np.allclose(poses[3][:3, 3], [1.0, 0.0, 1.25]) and np.allclose(poses[4][:3, 3], [1.8, 0.0, 1.25])


def test_settings_file_from_the_camera():
    intrinsics = Intrinsics.from_fov(320, 240, 90.0)
    text = settings_yaml(intrinsics, OrbSlam3Config(features=2000), fps_from_stamps(np.arange(10) * 0.1), 8.0)
    assert text.startswith("%YAML:1.0\n")
    values = dict(line.split(": ", 1) for line in text.splitlines()[2:])
    assert float(values["Camera1.fx"]) == pytest.approx(160.0) and values["Camera.width"] == "320"
    assert values["Camera.fps"] == "10" and values["ORBextractor.nFeatures"] == "2000"
    assert float(values["RGBD.DepthMapFactor"]) == 5000.0
    assert float(values["Stereo.ThDepth"]) * float(values["Stereo.b"]) == pytest.approx(8.0)  # the camera's range
    assert close_depth_factor(OrbSlam3Config(th_depth=40.0), 8.0) == 40.0


def test_bad_parameters_are_refused_with_the_range():
    with pytest.raises(Exception, match="features must be from 100 to 20000, got 10"):
        catalog.check_params("orbslam3", {"features": 10})
    with pytest.raises(Exception, match="min_th_fast"):
        catalog.check_params("orbslam3", {"ini_th_fast": 5, "min_th_fast": 9})


def test_console_counts_follow_global_bundle_adjustments():
    running = count_markers("*Loop detected\nStarting Global Bundle Adjustment\n")
    assert running.counts["loops"] == 1 and running.global_ba_running
    done = count_markers("*Loop detected\nStarting Global Bundle Adjustment\nGlobal Bundle Adjustment finished\n")
    assert not done.global_ba_running
    stopped = count_markers("Starting Global Bundle Adjustment\nStoping Global Bundle Adjustment...\n")
    assert not stopped.global_ba_running


# -- ORB-SLAM3 itself ---------------------------------------------------------------------------

def _pyorbslam3_loads() -> bool:
    probe = subprocess.run([sys.executable, "-c", "import pyorbslam3"], capture_output=True)
    return probe.returncode == 0


needs_orbslam3 = pytest.mark.skipif(not _pyorbslam3_loads(), reason="pyorbslam3 (or its system libraries) is not installed")
LONGSLAM = [sys.executable, "-m", "longslam"]


@pytest.fixture(scope="module")
def corridor(tmp_path_factory, rendered):
    """8 m down the spine (53 frames at 320 x 240, exact odometry) and a small vocabulary of it."""
    from longslam.vocabulary.build import build_vocabulary_file

    root = tmp_path_factory.mktemp("orbslam3")
    route = Route("corridor", "university", ((8.0, 31.25), (16.0, 31.25)))
    seq = rendered(route, "none", 0, CameraSettings())
    vocabulary = build_vocabulary_file(seq, root / "voc.txt", k=8, levels=3, seed=0, progress=False).path
    return root, seq, vocabulary


def _run(seq: Path, out: Path, vocabulary: Path, timeout: float = 300, pace: float = 1.0) -> subprocess.CompletedProcess:
    # Paced as in use (5 s for the corridor): fed faster, its mapping falls behind on a loaded machine.
    command = LONGSLAM + ["run", "--method", "orbslam3", str(seq), "--out", str(out),
                          "--param", f"vocabulary={vocabulary}", "--param", f"pace={pace}"]
    return subprocess.run(command, capture_output=True, text=True, timeout=timeout)


@needs_orbslam3
def test_registered_and_listed():
    assert "orbslam3" in catalog.method_names()
    listed = subprocess.run(LONGSLAM + ["list"], capture_output=True, text=True, check=True).stdout
    assert "orbslam3" in listed


@needs_orbslam3
def test_runs_into_the_world_frame_with_every_frame_posed(corridor):
    root, seq, vocabulary = corridor
    out = root / "run"
    done = _run(seq, out, vocabulary)
    assert done.returncode == 0, done.stderr
    assert "ORB-SLAM3" not in done.stdout + done.stderr  # its console is in the run's log
    assert "ORB-SLAM3" in (out / "console.log").read_text()
    truth = read_tum(seq / "groundtruth.txt")
    final, online = read_tum(out / "trajectory.txt"), read_tum(out / "online.txt")
    assert len(final) == len(online) == len(truth)
    # No alignment: it starts at the first odometry pose and must go where the robot went. A wrong
    # frame (optical z taken as up, a mirrored axis) is off by metres; ORB-SLAM3's own error on
    # these 8 m was 1.7-3.5 % of the distance in 4 runs (its threads make every run differ).
    error = np.linalg.norm(final.positions - truth.positions, axis=1)
    assert error.mean() < 0.25 and error[-1] < 0.5
    travelled, true_travel = final.positions[-1] - final.positions[0], truth.positions[-1] - truth.positions[0]
    assert abs(travelled[0] - true_travel[0]) < 0.05 * true_travel[0]  # down the spine (+x)
    assert abs(travelled[1]) < 0.3 and abs(travelled[2]) < 0.3
    heading = np.arctan2(final.poses[:, 1, 2], final.poses[:, 0, 2])  # the optical axis in the floor plane
    assert np.abs(heading).max() < np.radians(5)
    stats = json.loads((out / "stats.json").read_text())
    method = stats["method_stats"]
    assert sum(method["tracking_states"].values()) == len(truth)
    assert method["tracking_states"].get("OK", 0) >= len(truth) - 2
    assert method["vocabulary"]["source"] == "parameter"
    assert stats["process_cpu_time_s"] > 0
    assert (out / "orbslam3.yaml").is_file()


@needs_orbslam3
def test_survives_frames_it_cannot_track(corridor):
    """Black frames at the start (tracking cannot begin) and in the middle (tracking is lost)."""
    root, seq, vocabulary = corridor
    dark = root / "dark"
    shutil.copytree(seq, dark)
    names = [line.split()[1] for line in (dark / "rgb.txt").read_text().splitlines() if not line.startswith("#")]
    black = np.zeros((240, 320, 3), np.uint8)
    for i in list(range(0, 8)) + list(range(25, 33)):
        target = dark / names[i]
        target.unlink()  # the frames are hard links into the render cache: replace, don't write through
        cv2.imwrite(str(target), black)
    out = root / "dark-run"
    done = _run(dark, out, vocabulary, timeout=300, pace=0)
    assert done.returncode == 0, done.stderr
    truth = read_tum(dark / "groundtruth.txt")
    assert len(read_tum(out / "trajectory.txt")) == len(truth)
    method = json.loads((out / "stats.json").read_text())["method_stats"]
    assert method["frames_untracked"] >= 8
    assert set(method["tracking_states"]) - {"OK"}  # the states it went through are reported
    assert method["maps"] >= 1
    final = read_tum(out / "trajectory.txt")
    assert np.isfinite(final.poses).all()
    # Why: the stretch of black frames in the middle is an event of the run, with its frames.
    from longslam.run.folder import EVENTS, read_events

    losses = [e for e in read_events(out / EVENTS) if e.kind == "tracking_lost"]
    assert any(e.first_frame <= 26 and e.last_frame >= 31 for e in losses), losses
    assert method["tracking_lost_longest_s"] >= 0.7


BUSY = "import time\nend = time.time() + {s}\nwhile time.time() < end: pass\n"


@needs_orbslam3
def test_a_run_beside_busy_processes_reports_the_cpu_it_was_denied(corridor):
    """Two busy processes on the one core the run may use: its threads wait for it, and the run says so."""
    import os

    root, seq, vocabulary = corridor
    core = min(os.sched_getaffinity(0))
    pin = (lambda: os.sched_setaffinity(0, {core}))
    hogs = [subprocess.Popen([sys.executable, "-c", BUSY.format(s=240)], preexec_fn=pin) for _ in range(2)]
    try:
        out = root / "starved-run"
        command = LONGSLAM + ["run", "--method", "orbslam3", str(seq), "--out", str(out),
                              "--param", f"vocabulary={vocabulary}", "--param", "pace=0"]
        done = subprocess.run(command, capture_output=True, text=True, timeout=240, preexec_fn=pin)
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()
    assert done.returncode == 0, done.stderr
    stats = json.loads((out / "stats.json").read_text())
    assert stats["cpu_wait_share"] >= 0.2 and stats["starved"], stats["cpu_wait_share"]
    assert stats["cpu_wait_s"] > 0 and stats["tree_cpu_time_s"] > 0


WORD = " ".join(["7"] * 32)


@pytest.mark.parametrize("text, message", [
    ("garbage here\n1 2 3", "not a DBoW2 text vocabulary"),
    ("", "not a DBoW2 text vocabulary"),
    ("1 6 0 0\nx", "out of range"),
    # Each of these passed the header check, then ORB-SLAM3 segfaulted, stopped with a
    # RuntimeError after 48 s, or with "vector::reserve".
    (f"10 6 0 0\n999999 1 {WORD} 0.5", ":2: parent id 999999 must be a node before this one"),
    ("10 6 0 0\n" + "\n".join(["the quick brown fox jumps over the lazy dog"] * 50), ":2: expected 35 fields"),
    (f"20 10 0 0\n0 1 {WORD} 0.5", "vector::reserve"),
])
def test_a_file_that_is_no_vocabulary_is_refused(tmp_path, text, message):
    """pyorbslam3 would hand ORB-SLAM3 any file, which then tracks with garbage or crashes."""
    from longslam_orbslam3.vocabulary import resolve_vocabulary

    bad = tmp_path / "voc.txt"
    bad.write_text(text)
    with pytest.raises(Exception, match=message):
        resolve_vocabulary(str(bad))
    with pytest.raises(Exception, match="no such file"):
        resolve_vocabulary(str(tmp_path / "missing.txt"))


def _black_sequence(path: Path, depth: float, n: int = 20) -> Path:
    """`n` black 160 x 120 frames with flat depth (0: none), 10 Hz, driving 10 cm a frame."""
    from longslam.io.sequence import SequenceWriter

    stamps = 0.1 * np.arange(n)
    poses = camera_poses_from_planar(np.column_stack([3 + 0.1 * np.arange(n), np.full(n, 2.0), np.zeros(n)]), 1.25)
    with SequenceWriter(path, Intrinsics.from_fov(160, 120, 90.0), 8.0, {"route": "black"}) as writer:
        for t in stamps:
            writer.add(t, np.zeros((120, 160, 3), np.uint8), np.full((120, 160), depth, np.float32))
        writer.set_ground_truth(Trajectory(stamps, poses))
        writer.set_odometry(Trajectory(stamps, poses))
    return path


def _two_word_vocabulary(path: Path) -> Path:
    """The smallest vocabulary ORB-SLAM3 loads: k = 2, L = 1, two words (black frames give no features anyway)."""
    path.write_text("2 1 0 0\n" + "\n".join(f"0 1 {' '.join([str(b)] * 32)} 0" for b in (0, 255)))
    return path


@needs_orbslam3
@pytest.mark.parametrize("depth", [2.0, 0.0])
def test_a_run_where_orbslam3_makes_no_map_says_so(tmp_path, depth):
    """Black frames: ORB-SLAM3 never makes a map, and saving its trajectory then segfaulted (exit 139)."""
    seq = _black_sequence(tmp_path / "black", depth)
    out = tmp_path / "run"
    done = _run(seq, out, _two_word_vocabulary(tmp_path / "voc.txt"), timeout=120, pace=0)
    assert done.returncode == 0, (done.returncode, done.stderr[-2000:])
    assert "note: orbslam3: ORB-SLAM3 tracked none of the 20 frames and made no map" in done.stderr
    method = json.loads((out / "stats.json").read_text())["method_stats"]
    assert method["maps"] == 0 and method["frames_untracked"] == 20 and method["nodes"] == 0
    assert "made no map" in method["notes"][0]
    final, online = read_tum(out / "trajectory.txt"), read_tum(out / "online.txt")
    start = read_tum(seq / "odometry.txt").poses[0]
    assert len(final) == 20 and np.allclose(final.poses, start) and np.allclose(online.poses, start)


@needs_orbslam3
def test_a_map_reset_after_an_early_loss_leaves_no_map_and_no_crash(corridor):
    """Three frames tracked, then black: ORB-SLAM3 loses tracking with one keyframe, resets its
    only map, and its savers then stopped the run ("Invalid argument", or a segfault)."""
    root, seq, vocabulary = corridor
    dark = root / "dark-after-3"
    shutil.copytree(seq, dark)
    names = [line.split()[1] for line in (dark / "rgb.txt").read_text().splitlines() if not line.startswith("#")]
    black = np.zeros((240, 320, 3), np.uint8)
    for name in names[3:]:
        (dark / name).unlink()  # hard links into the render cache: replace, don't write through
        cv2.imwrite(str(dark / name), black)
    out = root / "dark-after-3-run"
    done = _run(dark, out, vocabulary, timeout=300, pace=0)
    assert done.returncode == 0, (done.returncode, done.stderr[-2000:])
    method = json.loads((out / "stats.json").read_text())["method_stats"]
    assert method["map_resets"] >= 1 and method["maps"] == 0 and method["frames_in_final"] == 0
    assert "reset it and made no map after" in done.stderr
    assert len(read_tum(out / "trajectory.txt")) == len(names)


@needs_orbslam3
def test_orbslam3_loads_the_largest_trees_longslam_accepts(tmp_path):
    """The bound on k and L (the loader reserves a full tree before reading a node) is ORB-SLAM3's:
    for a few k, the deepest L that longslam's check accepts loads in ORB-SLAM3 itself."""
    from longslam.vocabulary.dbow2 import loader_size_problem
    from longslam_orbslam3.vocabulary import resolve_vocabulary

    files = []
    for k in (2, 6, 10, 20):
        levels = max(L for L in range(1, 11) if loader_size_problem(k, L) is None)
        assert loader_size_problem(k, levels + 1) is not None or levels == 10
        path = _two_word_vocabulary(tmp_path / f"voc-{k}-{levels}.txt")
        path.write_text(path.read_text().replace("2 1 0 0", f"{k} {levels} 0 0", 1))
        resolve_vocabulary(str(path))  # the plugin's check passes it
        files.append(str(path))
    settings = tmp_path / "orbslam3.yaml"
    settings.write_text(settings_yaml(Intrinsics.from_fov(160, 120, 90.0), OrbSlam3Config(), 10.0, 8.0))
    script = ("import sys, pyorbslam3\n"
              "for path in sys.argv[2:]:\n"
              "    pyorbslam3.Slam(path, sys.argv[1], pyorbslam3.Sensor.RGBD, use_viewer=False).shutdown()\n"
              "    print('longslam-test-loaded', path, flush=True)\n")
    done = subprocess.run([sys.executable, "-c", script, str(settings), *files], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.count("longslam-test-loaded") == len(files)
