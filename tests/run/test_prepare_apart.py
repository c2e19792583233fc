"""`longslam run` does a method's once-per-machine work (ORB-SLAM3's default vocabulary: minutes
and some 300 MB) in a process of its own before the run, so the run's peak memory is its own."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from helpers.tiny_sequences import write_tiny_sequence
from longslam.slam.api import MethodSpec, Result
from longslam.core.trajectory import Trajectory

BUILD_BYTES = 400_000_000


def _prepare(config) -> None:
    """As the default vocabulary: built once into a cache (here a marker file), heavy to build."""
    marker = Path(config["marker"])
    if not marker.exists():
        block = np.ones(BUILD_BYTES, np.uint8)  # touched, so resident
        marker.write_text(str(int(block.sum())))


class Cached:
    """Calls the preparation itself, as the ORB-SLAM3 plugin resolves its vocabulary on start."""

    def __init__(self, context, config):
        _prepare(config)
        self.stamps: list[float] = []
        self.poses: list[np.ndarray] = []

    def step(self, frame):
        self.stamps.append(frame.timestamp)
        self.poses.append(np.array(frame.odometry))
        return self.poses[-1]

    def finish(self):
        t = Trajectory(np.array(self.stamps), np.array(self.poses))
        return Result(t, t)


SPEC = MethodSpec("cached", None, Cached, prepare=_prepare)


def test_run_prepares_apart_so_the_peak_is_the_runs(tmp_path):
    """In a fresh interpreter: a run's peak includes its process's own (ru_maxrss), which in the
    test session is whatever earlier tests reached."""
    import json
    import os
    import subprocess
    import sys

    seq = write_tiny_sequence(tmp_path / "seq", n=10)[0]
    marker = tmp_path / "built"
    here = Path(__file__).parent
    code = ("import sys; import test_prepare_apart as t; from longslam.slam.catalog import METHODS; "
            "METHODS.register('cached', t.SPEC); from longslam.cli.main import main; sys.exit(main(sys.argv[1:]))")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(here), str(here.parent), *sys.path])}
    done = subprocess.run([sys.executable, "-c", code, "run", "--method", "cached", str(seq), "--out", str(tmp_path / "run"),
                           "--param", f"marker={marker}"], env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert marker.exists()  # prepared, before the run
    peak = json.loads((tmp_path / "run" / "stats.json").read_text())["peak_rss_bytes"]
    assert peak < BUILD_BYTES, peak
