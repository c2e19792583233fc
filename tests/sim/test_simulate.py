"""simulate end to end on a short route with a small camera: cache reuse, odometry, interruption."""

import json
import os

import numpy as np
import pytest

from longslam.cli.main import main
from longslam.io.sequence import SequenceReader
from longslam.sim import simulate as cache_module
from longslam.sim.camera import CameraSettings
from longslam.core.odometry_noise import get_noise
from longslam.sim.routes import Route
from longslam.sim.simulate import simulate

pytestmark = pytest.mark.slow  # renders routes

SMALL = CameraSettings(width=64, height=48)
ROUTE = Route("short", "university", ((20.0, 31.25), (26.0, 31.25), "junction_a"))


@pytest.fixture()
def cache(tmp_path, monkeypatch):
    root = tmp_path / "cache"
    monkeypatch.setenv("LONGSLAM_CACHE", str(root))
    return root


def test_simulate_writes_a_sequence_and_reuses_the_rendering(cache, tmp_path):
    a = simulate(ROUTE, get_noise("large"), 1, tmp_path / "a", camera=SMALL, progress=False)
    rendered = list(cache.iterdir())
    assert len(rendered) == 1
    b = simulate(ROUTE, get_noise("small"), 2, tmp_path / "b", camera=SMALL, progress=False)
    assert list(cache.iterdir()) == rendered  # no second rendering
    ra, rb = SequenceReader(a), SequenceReader(b)
    assert len(ra) == len(rb) > 50
    # The frames are shared, the odometry is drawn per (noise, seed).
    first = sorted((a / "rgb").iterdir())[0]
    assert os.stat(first).st_ino == os.stat(b / "rgb" / first.name).st_ino
    assert not np.allclose(ra.odometry.poses, rb.odometry.poses)
    np.testing.assert_allclose(ra.odometry.poses[0], ra.ground_truth.poses[0], atol=1e-9)
    assert np.linalg.norm(ra.odometry.positions[-1] - ra.ground_truth.positions[-1]) > 1e-3
    meta = json.loads((a / "meta.json").read_text())
    assert (meta["noise"], meta["seed"], meta["route"]) == ("large", 1, "short")
    frame = ra.frame(10)
    assert frame.rgb.shape == (48, 64, 3) and frame.depth.dtype == np.float32
    assert 0.0 < frame.depth.max() <= 8.0
    # Same inputs and seed, same odometry.
    c = simulate(ROUTE, get_noise("large"), 1, tmp_path / "c", camera=SMALL, progress=False)
    np.testing.assert_array_equal(SequenceReader(c).odometry.poses, ra.odometry.poses)


def test_interrupted_simulate_leaves_nothing_half_written(cache, tmp_path, monkeypatch):
    calls = {"n": 0}
    real = cache_module.RGBDCamera.render

    def render_then_stop(self, pose):
        calls["n"] += 1
        if calls["n"] == 20:
            raise KeyboardInterrupt
        return real(self, pose)

    monkeypatch.setattr(cache_module.RGBDCamera, "render", render_then_stop)
    with pytest.raises(KeyboardInterrupt):
        simulate(ROUTE, get_noise("large"), 1, tmp_path / "seq", camera=SMALL, progress=False)
    assert not (tmp_path / "seq").exists()
    assert not cache.exists() or list(cache.iterdir()) == []
    monkeypatch.setattr(cache_module.RGBDCamera, "render", real)
    simulate(ROUTE, get_noise("large"), 1, tmp_path / "seq", camera=SMALL, progress=False)
    assert len(SequenceReader(tmp_path / "seq")) > 50


def test_cli_simulate_run_evaluate(cache, tmp_path, capsys):
    route = tmp_path / "route.txt"
    route.write_text("20 31.25\n27 31.25\n")
    seq, run = tmp_path / "seq", tmp_path / "run"
    args = ["--width", "64", "--height", "48"]
    assert main(["simulate", "--route", str(route), "--noise", "xlarge", "--seed", "4", "--out", str(seq), *args]) == 0
    assert main(["simulate", "--route", str(route), "--out", str(seq), *args]) == 2
    assert "exists already" in capsys.readouterr().err
    assert main(["run", "--method", "odometry", str(seq), "--out", str(run)]) == 0
    assert main(["evaluate", str(run), str(seq), "--json"]) == 0
    scores = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert scores["matched_poses"] == len(SequenceReader(seq))
    assert scores["ate"] > 0 and scores["e_trans"] > 0
    assert main(["world", "--route", str(route), "--out", str(tmp_path / "plan.png")]) == 0
    assert (tmp_path / "plan.png").stat().st_size > 10_000
