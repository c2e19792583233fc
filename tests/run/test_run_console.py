"""The method API for wrapped native systems: their console into the run's console.log, the CPU
time of their threads, and `close` when a run stops early."""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from longslam.core.errors import MethodError
from longslam.run import scored_run
from longslam.slam import catalog
from longslam.run.console import CONSOLE_LOG, native_output_to
from longslam.slam.api import MethodSpec, Result
from longslam.core.trajectory import Trajectory


class Native:
    """Writes to descriptors 1 and 2 as C++ code does, beside Python's own print."""

    name = "native"
    closed: list[str] = []

    def __init__(self, context, config):
        self.context = context
        self.poses: list[np.ndarray] = []
        self.stamps: list[float] = []
        os.write(1, b"native stdout at start\n")

    def step(self, frame):
        os.write(2, f"native stderr {frame.index}\n".encode())
        self.stamps.append(frame.timestamp)
        self.poses.append(np.array(frame.odometry))
        return self.poses[-1]

    def finish(self):
        t = Trajectory(np.array(self.stamps), np.array(self.poses))
        return Result(t, t, stats={"console_log": self.context.console_log})

    def close(self):
        Native.closed.append("closed")


class Fails(Native):
    name = "fails"

    def step(self, frame):
        if frame.index == 3:
            raise RuntimeError("failed at frame 3")
        return super().step(frame)


class Threaded(Native):
    """Its own thread burns CPU while `step` does nothing: only process CPU time sees it."""

    name = "threaded"

    def __init__(self, context, config):
        super().__init__(context, config)
        self.worker = threading.Thread(target=self._burn)

    def step(self, frame):
        if frame.index == 0:  # started with the run's clock, not before it
            self.worker.start()
        return super().step(frame)

    def _burn(self):
        start = time.thread_time()
        while time.thread_time() - start < 0.4:
            sum(range(1000))

    def finish(self):
        self.worker.join()
        return super().finish()


SPECS = {cls.name: MethodSpec(cls.name, None, cls) for cls in (Native, Fails, Threaded)}


@pytest.fixture(autouse=True)
def test_methods(method_catalogue):
    for name, spec in SPECS.items():
        method_catalogue.register(name, spec)
    Native.closed.clear()


def test_native_output_goes_to_the_run_console_log_not_the_terminal(tiny_sequence, tmp_path, capfd):
    scored_run.run_named("native", tiny_sequence, tmp_path / "run", progress=False)
    log = (tmp_path / "run" / CONSOLE_LOG).read_text()
    assert "native stdout at start" in log
    assert "native stderr 0" in log and "native stderr 19" in log
    captured = capfd.readouterr()
    assert "native" not in captured.out + captured.err
    import json

    told = json.loads((tmp_path / "run" / "stats.json").read_text())["method_stats"]["console_log"]
    assert Path(told).name == CONSOLE_LOG  # the method was told where its console goes


def test_python_output_still_reaches_the_terminal(tmp_path, capfd):
    import sys

    with native_output_to(tmp_path / "console.log"):
        print("from python", file=sys.stderr)
        os.write(2, b"from native\n")
    captured = capfd.readouterr()
    assert "from python" in captured.err and "from native" not in captured.err
    assert (tmp_path / "console.log").read_text() == "from native\n"


def test_an_empty_console_log_is_not_left(tmp_path):
    with native_output_to(tmp_path / "console.log"):
        pass
    assert not (tmp_path / "console.log").exists()


def test_descriptors_are_restored_after_an_error(tmp_path, capfd):
    with pytest.raises(RuntimeError):
        with native_output_to(tmp_path / "console.log"):
            raise RuntimeError("boom")
    os.write(1, b"after\n")
    assert "after" in capfd.readouterr().out


def test_close_is_called_when_a_run_fails_and_not_when_it_finishes(tiny_sequence, tmp_path):
    with pytest.raises(MethodError, match="frame 3"):
        scored_run.run_named("fails", tiny_sequence, tmp_path / "failed", progress=False)
    assert Native.closed == ["closed"]
    Native.closed.clear()
    scored_run.run_named("native", tiny_sequence, tmp_path / "ok", progress=False)
    assert Native.closed == []


def test_process_cpu_time_counts_the_method_threads(tiny_sequence, tmp_path):
    measurements = scored_run.run_named("threaded", tiny_sequence, tmp_path / "run", progress=False)
    assert measurements.process_cpu_time_s >= 0.4


@pytest.mark.slow
def test_the_demo_and_a_study_prepare_each_method_before_its_runs(tmp_path, monkeypatch):
    """MethodSpec.prepare: once-per-machine work outside every run's process and figures."""
    from longslam.cli import demo

    prepared = []
    spec = MethodSpec("native", None, Native, prepare=lambda config: prepared.append(dict(config)))
    monkeypatch.setattr(catalog, "get_spec", lambda name: spec)
    monkeypatch.setattr(demo, "get_spec", lambda name: spec)
    monkeypatch.setattr(demo, "run_and_score", lambda *a, **k: (_ for _ in ()).throw(RuntimeError("runs start")))
    from longslam.sim.camera import CameraSettings

    monkeypatch.setenv("LONGSLAM_CACHE", str(tmp_path / "cache"))
    with pytest.raises(RuntimeError, match="runs start"):
        demo.run_demo(tmp_path / "demo", methods=["native"], camera=CameraSettings(width=32, height=24), progress=False)
    assert prepared == [{}]
    spec.prepare_for({"a": 1})
    assert prepared[-1] == {"a": 1}
