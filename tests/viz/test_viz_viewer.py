"""The live view never hangs nor crashes a run (no display, a stuck viewer, a viewer closed in
the middle), and its recording: a blueprint, a UUID recording id with a readable name, a
`timestamp` timeline for wall-clock stamps, the paths sent a segment at a time, a JSON final log."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path

import numpy as np
import pytest

from helpers.tiny_sequences import TINY_INTRINSICS, write_tiny_sequence
from longslam.core.errors import InputError
from longslam.core.frame import Frame
from longslam.run.scored_run import run_named
from longslam.slam.api import MethodContext, Result
from longslam.core.trajectory import Trajectory

rerun = pytest.importorskip("rerun")
from rerun.chunk import RrdReader  # noqa: E402

from helpers.recordings import rows  # noqa: E402

import longslam.viz.live as live  # noqa: E402

pytestmark = pytest.mark.slow  # starts viewer processes

RUN_FILES = {"trajectory.txt", "online.txt", "stats.json", "config.toml"}


@pytest.fixture(scope="module")
def sequence(tmp_path_factory) -> Path:
    return write_tiny_sequence(tmp_path_factory.mktemp("viewer") / "seq", n=25, turn=1.0)[0]


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def run_cli(sequence: Path, out: Path, port: int, env: dict, wait_s: float = 2.0,
            timeout: float = 60.0) -> tuple[subprocess.CompletedProcess, float]:
    """`longslam run --viz` in a process of its own, its viewer port set to `port`, under a timeout."""
    code = (f"import sys, longslam.viz.live as live; live.VIEWER_PORT = {port}; live.VIEWER_WAIT_S = {wait_s}\n"
            "from longslam.cli.main import main\n"
            f"sys.exit(main(['run', '--method', 'odometry', {str(sequence)!r}, '--out', {str(out)!r}, '--viz']))")
    start = time.monotonic()
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=timeout)
    return done, time.monotonic() - start


def error_lines(done: subprocess.CompletedProcess) -> list[str]:
    # tqdm's bar is off when stderr is not a terminal only on some branches: keep the error lines
    return [line for line in done.stderr.replace("\r", "\n").splitlines() if "error" in line.lower()]


def test_no_display_is_refused_at_once(sequence, tmp_path):
    # DISPLAY names an X server that is not there (a session that ended): the viewer would die
    number = next(n for n in range(4711, 4800) if not os.path.exists(f"/tmp/.X11-unix/X{n}"))
    env = {k: v for k, v in os.environ.items() if k != "WAYLAND_DISPLAY"}
    env["DISPLAY"] = f":{number}"
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"  # a viewer is installed
    done, took = run_cli(sequence, tmp_path / "run", free_port(), env)
    assert done.returncode == 2, done.stderr
    (line,) = error_lines(done)
    assert f"no X server answers on DISPLAY=:{number}" in line and "--viz run.rrd" in line
    assert "Traceback" not in done.stderr and took < 30
    assert list(tmp_path.iterdir()) == []  # refused before any work


def test_a_viewer_that_dies_at_start_is_refused_before_any_work(sequence, tmp_path):
    # a display to talk to (a Wayland socket that listens), and a viewer that cannot open a window
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "rerun").write_text("#!/bin/sh\necho 'viewer: no GPU adapter found' >&2\nexit 1\n")
    (bin_dir / "rerun").chmod(0o755)
    wayland = socket.socket(socket.AF_UNIX)
    wayland.bind(str(tmp_path / "wayland-0"))
    wayland.listen(16)
    env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
    env.update(WAYLAND_DISPLAY=str(tmp_path / "wayland-0"), PATH=f"{bin_dir}{os.pathsep}{env.get('PATH', '')}")
    try:
        done, took = run_cli(sequence, tmp_path / "run", free_port(), env)
    finally:
        wayland.close()
    assert done.returncode == 2, done.stderr
    (line,) = error_lines(done)
    assert f"the rerun viewer {bin_dir / 'rerun'} did not start" in line and "--viz run.rrd" in line
    assert "viewer: no GPU adapter found" in done.stderr  # the viewer's own words, above
    assert took < 40 and "Traceback" not in done.stderr
    assert not (tmp_path / "run").exists()


class SilentViewer:
    """A server that accepts connections and never reads: a viewer that hangs."""

    def __init__(self) -> None:
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.port = self.sock.getsockname()[1]
        self.held: list[socket.socket] = []
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            self.held.append(conn)

    def close(self) -> None:
        self.sock.close()
        for conn in self.held:
            conn.close()


def test_a_stuck_viewer_never_holds_the_run(sequence, tmp_path):
    viewer = SilentViewer()
    try:
        done, took = run_cli(sequence, tmp_path / "run", viewer.port, dict(os.environ), wait_s=2.0)
    finally:
        viewer.close()
    assert done.returncode == 2, done.stderr
    (line,) = error_lines(done)
    assert "the rerun viewer stopped taking data" in line and "files are complete" in line
    assert took < 40 and "Traceback" not in done.stderr
    assert RUN_FILES <= {p.name for p in (tmp_path / "run").iterdir()}  # the run's files intact
    assert len((tmp_path / "run/trajectory.txt").read_text().splitlines()) == 26  # header + 25 poses


def test_a_viewer_closed_in_the_middle_of_a_run(sequence, tmp_path, monkeypatch):
    port = free_port()
    # `rerun` is a Python launcher of the viewer binary: a session of its own, to stop both
    server = subprocess.Popen([str(Path(sys.executable).parent / "rerun"), "--serve-grpc", "--port", str(port)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)

    def stop() -> None:
        if server.poll() is None:
            os.killpg(server.pid, signal.SIGKILL)
        server.wait()
        while live._viewer_listening(port):  # the binary, a moment after its launcher
            time.sleep(0.05)

    try:
        deadline = time.monotonic() + 30
        while not live._viewer_listening(port):
            assert time.monotonic() < deadline and server.poll() is None, "rerun --serve-grpc did not start"
            time.sleep(0.1)
        monkeypatch.setattr(live, "VIEWER_PORT", port)
        monkeypatch.setattr(live, "VIEWER_WAIT_S", 2.0)
        # a viewer that stays: the run streams to it and ends as usual
        figures = run_named("odometry", sequence, tmp_path / "shown", progress=False, viz="viewer")
        assert figures.frames == 25 and figures.observer_time_s > 0
        # the viewer goes away before the run ends: the run finishes, its folder whole, and says so
        finish = live.LiveView._finish

        def close_viewer_then_finish(view, result):
            stop()
            finish(view, result)

        monkeypatch.setattr(live.LiveView, "_finish", close_viewer_then_finish)
        with pytest.raises(InputError, match="the rerun viewer stopped taking data .*the run itself finished"):
            run_named("odometry", sequence, tmp_path / "run", progress=False, viz="viewer")
        assert RUN_FILES <= {p.name for p in (tmp_path / "run").iterdir()}
    finally:
        stop()




def test_each_recording_has_its_own_id_a_name_and_a_blueprint(sequence, tmp_path):
    ids = []
    for k in range(2):  # the same run twice: two recordings, never merged
        rrd = tmp_path / f"run{k}.rrd"
        run_named("odometry", sequence, tmp_path / f"run{k}", progress=False, viz=str(rrd))
        (recording,) = RrdReader(rrd).recordings()
        assert recording.application_id == "longslam"
        ids.append(str(uuid.UUID(recording.recording_id)))  # a UUID
        assert rows(rrd, "/__properties", "RecordingInfo:name") == [["odometry on seq"]]
    assert ids[0] != ids[1]
    # the default blueprint: the 3D world, the two images, the error over time
    reader = RrdReader(tmp_path / "run0.rrd")
    (store,) = reader.blueprints()
    views = {}
    for chunk in reader.stream(store=store):
        batch = chunk.to_record_batch()
        if "ViewBlueprint:class_identifier" in batch.schema.names:
            (kind,), (origin,) = batch.column("ViewBlueprint:class_identifier")[0].as_py(), batch.column("ViewBlueprint:space_origin")[0].as_py()
            views.setdefault(kind, []).append(origin)
    assert views == {"3D": ["world"], "2D": ["world/camera/image"] * 2, "TimeSeries": ["error"]}


def test_wall_clock_stamps_the_paths_a_segment_at_a_time_and_a_json_log(tmp_path):
    stamps = 1_305_031_102.175304 + 0.1 * np.arange(23)  # a TUM sequence's stamps
    poses = np.repeat(np.eye(4)[None], len(stamps), axis=0)
    poses[:, 0, 3] = 0.1 * np.arange(len(stamps))
    rgb, depth = np.zeros((12, 16, 3), np.uint8), np.ones((12, 16), np.float32)
    with live.LiveView(str(tmp_path / "v.rrd"), "fake on tum", every=5) as view:
        view.start(object(), MethodContext(TINY_INTRINSICS, 8.0))
        for k, t in enumerate(stamps):
            view.frame(Frame(k, float(t), rgb, depth, poses[k], TINY_INTRINSICS), poses[k], object())
        view.finish(Result(Trajectory(stamps, poses), Trajectory(stamps, poses), stats={"nodes": 3, "loops": 0.5}))
    rrd = tmp_path / "v.rrd"
    # a `timestamp` timeline of the real stamps, beside the frame index and the time since the start
    logged = rows(rrd, "/world/camera", "timestamp")
    np.testing.assert_allclose([t.value / 1e9 for t in logged], stamps, rtol=0, atol=1e-6)
    assert rows(rrd, "/world/camera", "frame") == list(range(23))
    assert [d.value / 1e9 for d in rows(rrd, "/world/camera", "time")] == pytest.approx(stamps - stamps[0], abs=1e-6)
    # the estimate: one new segment every 5 frames (and the rest at the end), each point sent once
    # but for the joint with the segment before
    segments = [rows(rrd, f"/world/estimate/{k}", "LineStrips3D:strips") for k in range(6)]
    assert segments[5] == [] and all(len(s) == 1 for s in segments[:5])
    strips = [np.array(s[0][0]) for s in segments[:5]]
    assert [len(s) for s in strips] == [6, 6, 6, 6, 3]
    np.testing.assert_allclose(np.vstack([strips[0]] + [s[1:] for s in strips[1:]]), poses[:, :3, 3], atol=1e-6)
    # the final log is JSON
    texts = sorted(text for (text,) in rows(rrd, "/run", "TextLog:text"))
    assert texts[0] == "fake on tum" and texts[1].startswith("finished: ") and len(texts) == 2
    assert json.loads(texts[1][len("finished: "):]) == {"nodes": 3, "loops": 0.5}


def test_a_simulated_sequence_has_no_wall_clock_timeline(sequence, tmp_path):
    run_named("odometry", sequence, tmp_path / "run", progress=False, viz=str(tmp_path / "v.rrd"))
    assert rows(tmp_path / "v.rrd", "/world/camera", "timestamp") == []  # stamps from 0: not dates in 1970
    assert len(rows(tmp_path / "v.rrd", "/world/camera", "time")) == 25
