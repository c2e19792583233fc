"""The live view: a run recorded to a .rrd file, read back; no cost and no rerun import when off."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from helpers.tiny_sequences import write_tiny_sequence
from longslam.cli.main import main
from longslam.core.errors import InputError
from longslam.io.trajectory_files import read_tum
from longslam.run.scored_run import run_named

rerun = pytest.importorskip("rerun")
from rerun.chunk import RrdReader  # noqa: E402

from helpers.recordings import rows  # noqa: E402

pytestmark = pytest.mark.slow  # runs methods with the live view, some in processes


@pytest.fixture(scope="module")
def turning(tmp_path_factory) -> Path:
    return write_tiny_sequence(tmp_path_factory.mktemp("viz") / "seq", n=25, turn=1.0, odometry_scale=1.05)[0]


def test_a_run_recorded_to_rrd(turning, tmp_path):
    plain = run_named("keyframe", turning, tmp_path / "plain", {"frontend.mode": "wheel"}, progress=False)
    shown = run_named("keyframe", turning, tmp_path / "shown", {"frontend.mode": "wheel"}, progress=False,
                         viz=str(tmp_path / "run.rrd"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plain", "run.rrd", "shown"]  # no partial left
    # the view changes nothing in the run, and its cost is measured apart
    np.testing.assert_array_equal(read_tum(tmp_path / "plain/trajectory.txt").poses, read_tum(tmp_path / "shown/trajectory.txt").poses)
    assert plain.observer_time_s is None and shown.observer_time_s > 0

    (recording,) = RrdReader(tmp_path / "run.rrd").recordings()
    assert recording.application_id == "longslam"  # its id and name: test_viz_viewer.py
    entities = {chunk.entity_path for chunk in RrdReader(tmp_path / "run.rrd").stream()}
    assert {"/world/truth", "/world/estimate/0", "/world/odometry/0", "/world/final", "/world/camera",
            "/world/camera/image", "/world/camera/image/rgb", "/world/camera/image/depth", "/error/position",
            "/world/map/0", "/world/map/2"} <= entities
    # one camera pose and one image pair per frame; the true path as the sequence has it
    assert len(rows(tmp_path / "run.rrd", "/world/camera", "Transform3D:translation")) == 25
    assert len(rows(tmp_path / "run.rrd", "/world/camera/image/depth", "DepthImage:buffer")) == 25
    truth = rows(tmp_path / "run.rrd", "/world/truth", "LineStrips3D:strips")[0][0]
    np.testing.assert_allclose(truth[-1], [0.15 * 24, 0.0, 1.25], atol=1e-5)
    # the position error grows with the odometry's 5 % scale error
    errors = [e[0] for e in rows(tmp_path / "run.rrd", "/error/position", "Scalars:scalars")]
    assert len(errors) == 25 and errors[0] == pytest.approx(0.0, abs=1e-6) and errors[-1] > 0.1


def test_loop_constraints_are_drawn_between_graph_nodes(tmp_path):
    from longslam.core.frame import Frame
    from longslam.slam.api import MethodContext, Result
    from longslam.slam.graph import PoseGraph
    from longslam.core.trajectory import Trajectory
    from longslam.viz.live import LiveView
    from helpers.tiny_sequences import TINY_INTRINSICS

    class WithGraph:  # any method with a public PoseGraph
        graph = PoseGraph()

    m = WithGraph()
    m.graph.add_node(0, (0.0, 0.0, 0.0))
    m.graph.add_node(1, (2.0, 0.0, 0.0))
    m.graph.add_node(2, (2.0, 3.0, 0.0))
    m.graph.add_odometry(0, 1, (2.0, 0.0, 0.0), sigmas=(0.1, 0.1, 0.1))
    m.graph.add_odometry(1, 2, (0.0, 3.0, 0.0), sigmas=(0.1, 0.1, 0.1))
    m.graph.add_loop(0, 2, (2.0, 3.0, 0.0), sigmas=(0.1, 0.1, 0.1))
    pose = np.eye(4)
    pose[2, 3] = 1.25
    frame = Frame(0, 0.0, np.zeros((12, 16, 3), np.uint8), np.ones((12, 16), np.float32), None, TINY_INTRINSICS)
    with LiveView(str(tmp_path / "loops.rrd"), "fake") as view:
        view.start(m, MethodContext(TINY_INTRINSICS, 8.0))
        view.frame(frame, pose, m)
        view.finish(Result(Trajectory(np.zeros(1), pose[None]), Trajectory(np.zeros(1), pose[None])))
    (strips,) = rows(tmp_path / "loops.rrd", "/world/loops", "LineStrips3D:strips")
    np.testing.assert_allclose(strips, [[[0.0, 0.0, 1.25], [2.0, 3.0, 1.25]]])  # the loop only, not the odometry
    points = rows(tmp_path / "loops.rrd", "/world/map/0", "Points3D:positions")[0]
    assert len(points) == 4  # 16 x 12 depth at stride 8: 2 x 2 points, 1 m ahead
    np.testing.assert_allclose(np.array(points)[:, 2], 2.25)


def test_no_viz_no_rerun(turning, tmp_path):
    code = ("import sys; from longslam.run.scored_run import run_named; "
            f"run_named('odometry', {str(turning)!r}, {str(tmp_path / 'r')!r}, progress=False); "
            "assert 'rerun' not in sys.modules, 'rerun imported without --viz'")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_bad_viz_target_is_refused_before_any_work(turning, tmp_path, capsys):
    assert main(["run", "--method", "odometry", str(turning), "--out", str(tmp_path / "r"), "--viz", str(tmp_path / "x.txt")]) == 2
    assert "expected no value (a live viewer) or a file ending in .rrd" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()
    with pytest.raises(InputError, match="does not exist"):
        run_named("odometry", turning, tmp_path / "r", viz=str(tmp_path / "no" / "x.rrd"), progress=False)
