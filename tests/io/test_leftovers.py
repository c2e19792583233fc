"""What killed processes leave behind is cleaned by the next writer; folders get ordinary modes."""

import os
import stat
import subprocess
import time

import numpy as np
import pytest

from longslam.core.frame import Intrinsics
from longslam.core.geometry import camera_poses_from_planar
from longslam.io.partials import clean_stale_partials
from longslam.io.sequence import SequenceWriter
from longslam.run.scored_run import run_named
from longslam.sim.simulate import simulate
from longslam.sim.camera import CameraSettings
from longslam.core.odometry_noise import get_noise
from longslam.sim.routes import Route
from longslam.core.trajectory import Trajectory


def _dead_pid() -> int:
    proc = subprocess.Popen(["true"])
    proc.wait()
    return proc.pid


def _write(path, n=5):
    stamps = 0.1 * np.arange(n)
    poses = camera_poses_from_planar(np.column_stack([0.1 * np.arange(n), np.zeros(n), np.zeros(n)]), 1.25)
    with SequenceWriter(path, Intrinsics.from_fov(16, 12, 90.0), 8.0, {"route": "t"}) as writer:
        for t in stamps:
            writer.add(t, np.zeros((12, 16, 3), np.uint8), np.ones((12, 16), np.float32))
        writer.set_ground_truth(Trajectory(stamps, poses))
        writer.set_odometry(Trajectory(stamps, poses))
    return path


def _leftovers(folder, pid, age=3600.0):
    run = folder / f".run.partial-{pid}"
    seq = folder / f".seq.partial-{pid}-k3x9"
    for path in (run, seq):
        (path / "rgb").mkdir(parents=True)
        old = time.time() - age  # left an hour ago
        os.utime(path, (old, old))
    return run, seq


def test_a_run_cleans_partials_whose_process_is_gone(tmp_path):
    seq = _write(tmp_path / "in" / "seq")
    dead = _leftovers(tmp_path, _dead_pid())
    alive = _leftovers(tmp_path / "busy", os.getpid())
    # A dead PID whose partial is still being modified may be another machine's, on a shared disk.
    fresh = _leftovers(tmp_path / "shared", _dead_pid(), age=0.0)
    other = tmp_path / ".notes.txt"
    other.write_text("mine")
    run_named("odometry", seq, tmp_path / "run", progress=False)
    assert not any(p.exists() for p in dead)
    assert all(p.exists() for p in alive) and other.exists()
    assert clean_stale_partials(tmp_path / "busy") == []  # this process is alive
    assert clean_stale_partials(tmp_path / "shared") == [] and all(p.exists() for p in fresh)


@pytest.mark.slow
def test_a_render_cleans_partials_in_its_cache(tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    dead = _leftovers(cache, _dead_pid())
    monkeypatch.setenv("LONGSLAM_CACHE", str(cache))
    route = Route("tiny", "university", ((20.0, 31.25), (21.0, 31.25)))
    simulate(route, get_noise("none"), 0, tmp_path / "seq", camera=CameraSettings(width=32, height=24), progress=False)
    assert not any(p.exists() for p in dead)


def test_sequences_and_the_cache_get_the_modes_mkdir_gives(tmp_path, monkeypatch):
    old = os.umask(0o022)
    try:
        cache = tmp_path / "cache"
        monkeypatch.setenv("LONGSLAM_CACHE", str(cache))
        route = Route("tiny", "university", ((20.0, 31.25), (21.0, 31.25)))
        out = simulate(route, get_noise("none"), 0, tmp_path / "seq", camera=CameraSettings(width=32, height=24), progress=False)
        written = _write(tmp_path / "written")
        for folder in (out, written, *cache.iterdir()):
            if folder.is_dir():
                assert stat.S_IMODE(folder.stat().st_mode) == 0o755, folder
    finally:
        os.umask(old)


def test_a_same_host_partial_whose_process_is_gone_is_removed_at_once(tmp_path):
    import subprocess

    from longslam.io.partials import clean_stale_partials, host_tag, partial_path

    proc = subprocess.Popen(["true"])
    proc.wait()
    mine = partial_path(tmp_path / "run", proc.pid)  # just written: no idle wait on this machine
    assert host_tag() in mine.name and mine.name.startswith(".run.partial-")
    mine.mkdir()
    alive = partial_path(tmp_path / "busy")  # this process's
    alive.mkdir()
    elsewhere = tmp_path / f".run2.partial-{proc.pid}@another_machine"
    elsewhere.mkdir()
    assert clean_stale_partials(tmp_path) == [mine]
    assert alive.exists() and elsewhere.exists()
    old = time.time() - 2 * 24 * 3600
    os.utime(elsewhere, (old, old))
    assert clean_stale_partials(tmp_path) == [elsewhere]
