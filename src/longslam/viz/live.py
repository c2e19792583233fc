"""A run shown live in a rerun viewer, or recorded to a .rrd file (`longslam run ... --viz`).

An observer of the run engine (`run/observer.py`): it sees each frame and the pose the method
returned, and reads a method's pose graph (`slam.api.pose_graph`, part of the method interface) for its loop
constraints; the methods know nothing of it. rerun (the optional extra `longslam[viz]`) is
imported only here, when a view is asked for.

Each view is a recording of its own (a UUID recording id, named "<method> on <sequence>"), so
re-runs never merge, with a default blueprint: the 3D world, the colour and depth images, and the
position error over time. Timelines: `frame` (the index), `time` (since the first frame) and,
when the sequence's stamps are wall-clock times (a real TUM sequence), `timestamp`.

Entities (world z up):

    world/truth               the true trajectory (the sequence's ground truth), once
    world/estimate/<k>        the method's online trajectory, a new segment every `every` frames
    world/odometry/<k>        the wheel odometry, likewise
    world/loops               the method's graph constraints other than odometry, as lines
    world/map/<n>             a sparse coloured cloud of every `every`-th frame at its online pose
    world/camera              the current camera pose; world/camera/image: its pinhole, with
    world/camera/image/rgb    the current colour image and
    world/camera/image/depth  the current depth (millimetres)
    error/position            the online estimate's distance to the true pose (m)
    world/final               the final trajectory, at the end
    run                       the run's name, and at the end its stats as JSON

A view never stops a run nor hangs it: a viewer that cannot be shown (none installed, no display)
is refused before any work; one that stops taking data (closed, crashed, stuck) is given up and
the run goes on; either way `InputError` (exit 2) says so in one line, after the run's folder
is complete.
"""

from __future__ import annotations

import json
import os
import socket
import sys
import threading
import uuid
from pathlib import Path
from typing import Any, Literal

import numpy as np

from longslam.core.errors import InputError
from longslam.core.frame import Frame
from longslam.core.jsonable import json_default
from longslam.core.timestamps import nearest_indices
from longslam.core.trajectory import Trajectory
from longslam.io.atomic import rename_no_replace, replace_file
from longslam.io.overwrite_policy import check_output_file_free
from longslam.io.partials import partial_path
from longslam.slam.api import MethodContext, Result, pose_graph
from longslam.slam.graph import ODOMETRY

VIEWER = "viewer"  # --viz without a file: spawn (or join) a viewer on this machine
COLORS = {
    "truth": (60, 200, 60),
    "estimate": (230, 60, 40),
    "odometry": (120, 120, 120),
    "final": (40, 90, 230),
    "loop": (250, 200, 0),
    "registration": (180, 60, 220),
}
TRUTH_MAX_DIFF = 0.02  # s: the true pose compared with each frame's estimate
WALL_CLOCK_AFTER_S = 86_400.0  # a first stamp past a day: the sequence's stamps are wall-clock times
# At the end, a viewer that has not taken the run's data after this long is gone or stuck. With
# the second left for closing the stream it stays under the 10 s after which rerun itself warns
# ("will keep waiting") and then waits for ever.
VIEWER_WAIT_S = 6.0
CLOSE_AFTER_TIMEOUT_S = 1.0


def require_rerun() -> Any:
    try:
        import rerun
    except ImportError:
        raise InputError(
            "--viz needs rerun: pip install 'longslam[viz]' (or the version pinned in requirements.lock)"
        ) from None
    return rerun


def find_viewer() -> str:
    """The rerun viewer's executable: on PATH, or beside this Python (a virtual environment that is
    not activated has it in its bin/ only). InputError if there is none, before any work."""
    import shutil

    found = shutil.which("rerun") or shutil.which("rerun", path=str(Path(sys.executable).parent))
    if found is None:
        raise InputError(
            "--viz: the rerun viewer (the `rerun` command of rerun-sdk) is not on PATH nor beside "
            f"{sys.executable}; install it (pip install 'longslam[viz]'), or record to a file: --viz run.rrd"
        )
    return found


VIEWER_PORT = 9876  # rerun's default: a viewer already listening there is joined


def _viewer_listening(port: int | None = None) -> bool:
    try:
        with socket.create_connection(("127.0.0.1", VIEWER_PORT if port is None else port), timeout=0.5):
            return True
    except OSError:
        return False


def _display_problem() -> str | None:
    """Why a window cannot open here (Linux: no X or Wayland server to talk to), or None. A
    viewer spawned without one dies at once, and a DISPLAY left from a closed session is as bad
    as none."""
    if not sys.platform.startswith("linux"):
        return None
    wayland = os.environ.get("WAYLAND_DISPLAY")
    if wayland:
        runtime = os.environ.get("XDG_RUNTIME_DIR", f"/run/user/{os.getuid()}")
        if _unix_socket_answers(wayland if os.path.isabs(wayland) else os.path.join(runtime, wayland)):
            return None
    display = os.environ.get("DISPLAY")
    if not display:
        if wayland:
            return f"WAYLAND_DISPLAY={wayland} has no server listening and DISPLAY is unset"
        return "DISPLAY and WAYLAND_DISPLAY are unset"
    host, _, rest = display.rpartition(":")
    number = rest.split(".")[0]
    if not number.isdigit():
        return f"DISPLAY={display} is not of the form [host]:number"
    if host in ("", "unix"):
        path = f"/tmp/.X11-unix/X{number}"
        if _unix_socket_answers(path) or _unix_socket_answers("\0" + path):  # the file, or Linux's abstract socket
            return None
        return f"no X server answers on DISPLAY={display}"
    try:
        with socket.create_connection((host, 6000 + int(number)), timeout=1.0):
            return None
    except OSError:
        return f"no X server answers on DISPLAY={display} ({host}, port {6000 + int(number)})"


def _unix_socket_answers(path: str) -> bool:
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
        sock.settimeout(1.0)
        try:
            sock.connect(path)
            return True
        except OSError:
            return False


def check_viewer() -> str | None:
    """The viewer to start, or None to join one already running; InputError if neither can be:
    without a display a spawned viewer dies at once and the run would stream to nobody."""
    if _viewer_listening():
        return None
    viewer = find_viewer()
    problem = _display_problem()
    if problem is not None:
        raise InputError(
            f"--viz: there is no display to show the rerun viewer on ({problem}) and no viewer is "
            "running; record to a file instead (--viz run.rrd) and open it with `rerun run.rrd` "
            "where there is a screen"
        )
    return viewer


def blueprint() -> Any:
    """The default layout: the 3D world beside the camera's images and the error over time."""
    import rerun.blueprint as rrb

    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(name="world", origin="world"),
            rrb.Vertical(
                rrb.Spatial2DView(name="colour", origin="world/camera/image", contents=["$origin/rgb"]),
                rrb.Spatial2DView(name="depth", origin="world/camera/image", contents=["$origin/depth"]),
                rrb.TimeSeriesView(name="position error (m)", origin="error"),
            ),
            column_shares=[2, 1],
        ),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),  # the time panel stays: it scrubs through the run
    )


def check_target(target: str, overwrite: bool = False) -> None:
    """Refuse a --viz value that is neither the viewer nor a writable .rrd path, before any work;
    an existing .rrd file is replaced only with `overwrite`, as run folders are."""
    if target == VIEWER:
        check_viewer()
        return
    path = Path(target)
    if path.suffix != ".rrd":
        raise InputError(f"--viz {target}: expected no value (a live viewer) or a file ending in .rrd")
    if path.is_dir():
        raise InputError(f"--viz {target} is a folder; expected a .rrd file")
    parent = path.absolute().parent
    if not parent.is_dir():
        raise InputError(f"--viz {target}: the folder {parent} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"--viz {target}: the folder {parent} is not writable")
    check_output_file_free(path, overwrite, "--viz")  # an existing file only if it is a recording


class LiveView:
    """Streams a run to rerun. Use as a context manager; a .rrd file appears only when complete."""

    images_every_frame = ("rgb", "depth")  # shown every frame: the engine decodes them ahead

    def __init__(
        self,
        target: str,
        name: str,
        truth: Trajectory | None = None,
        every: int = 10,
        map_stride: int = 8,
        overwrite: bool = False,
    ):
        check_target(target, overwrite)
        self.rr = require_rerun()
        self.target = target
        self.overwrite = overwrite
        self.name = name
        self.truth = truth
        self.every = max(int(every), 1)
        self.map_stride = max(int(map_stride), 1)
        self._tmp: Path | None = None
        self.lost: str | None = None  # why the viewer stopped taking data
        # A fresh id per view: rerun merges everything sent under one recording id.
        self.recording_id = str(uuid.uuid4())
        self.rec = self.rr.RecordingStream("longslam", recording_id=self.recording_id)
        layout = blueprint()
        if target == VIEWER:
            try:
                viewer = check_viewer()
                if viewer is not None:
                    self.rr.spawn(executable_path=viewer, port=VIEWER_PORT, connect=False, recording=self.rec)
                    if not _viewer_listening():  # it died at once (no GPU, a display it could not open...)
                        raise InputError(
                            f"--viz: the rerun viewer {viewer} did not start (nothing listens on port "
                            f"{VIEWER_PORT}; its own message, if any, is above); record to a file "
                            "instead: --viz run.rrd"
                        )
                self.rec.connect_grpc(f"rerun+http://127.0.0.1:{VIEWER_PORT}/proxy", default_blueprint=layout)
                self.rec.send_recording_name(name)
            except RuntimeError as err:
                raise InputError(
                    f"--viz: the rerun viewer could not be reached ({_first_line(err)}); "
                    "record to a file instead: --viz run.rrd"
                ) from None
        else:
            path = Path(target)
            self._tmp = partial_path(path)
            self.rec.save(self._tmp, default_blueprint=layout)
            self.rec.send_recording_name(name)
        self._estimate: list[np.ndarray] = []
        self._odometry: list[np.ndarray] = []
        self._drawn = {"estimate": 0, "odometry": 0}  # points already sent, per path
        self._segments = {"estimate": 0, "odometry": 0}
        self._map_chunks = 0
        self._first_stamp: float | None = None

    def __enter__(self) -> "LiveView":
        return self

    def __exit__(self, exc_type, exc, tb) -> Literal[False]:
        if self.target == VIEWER:
            self._close_viewer_stream()
        else:  # a file takes everything, however long
            self.rec.flush()
            self.rec.disconnect()
        if self._tmp is not None:
            if exc_type is None and self.lost is None:
                if self.overwrite:
                    try:
                        replace_file(self._tmp, self.target)
                    except InputError:  # a FIFO or a device put there meanwhile: kept
                        self._tmp.unlink()
                        raise
                else:  # a file another process wrote meanwhile is kept
                    try:
                        rename_no_replace(self._tmp, self.target)
                    except FileExistsError:
                        self._tmp.unlink()
                        raise InputError(
                            f"--viz {self.target} was written by another process while this run "
                            "went on; it was left as it is (pass --overwrite to replace it)"
                        ) from None
            elif self._tmp.exists():
                self._tmp.unlink()
        if exc_type is None and self.lost is not None:
            where = "the rerun viewer" if self.target == VIEWER else f"--viz {self.target}"
            raise InputError(
                f"--viz: {where} stopped taking data ({self.lost}); the run itself finished and its "
                "files are complete"
            )
        return False

    def _close_viewer_stream(self) -> None:
        """Flush and close the stream to the viewer, waiting at most VIEWER_WAIT_S: rerun waits
        without end for a viewer that accepted the connection and stopped reading."""
        if self.lost is None:
            try:
                self.rec.flush(timeout_sec=VIEWER_WAIT_S)
            except RuntimeError as err:
                self.lost = _first_line(err)

        def close() -> None:
            try:
                self.rec.disconnect()
            except RuntimeError as err:
                self.lost = self.lost or _first_line(err)

        closing = threading.Thread(target=close, name="rerun-disconnect", daemon=True)
        closing.start()
        closing.join(VIEWER_WAIT_S if self.lost is None else CLOSE_AFTER_TIMEOUT_S)
        if closing.is_alive():
            self.rr.unregister_shutdown()  # its exit handler would wait for the same stream, for ever
            self.lost = self.lost or f"it took none of the data for {VIEWER_WAIT_S:g} s"
        elif self.lost is None and not _viewer_listening():
            # closed or crashed: rerun drops what it could not send without a word
            self.lost = f"it is no longer running on port {VIEWER_PORT}"

    def _guarded(self, call, *args) -> None:
        """One observer call; rerun failing there gives the view up, never the run."""
        if self.lost is not None:
            return
        try:
            call(*args)
        except (RuntimeError, OSError) as err:
            self.lost = _first_line(err)

    # the observer ----------------------------------------------------------------

    def start(self, method: Any, context: MethodContext) -> None:
        self._guarded(self._start, method, context)

    def frame(self, frame: Frame, pose: np.ndarray, method: Any) -> None:
        self._guarded(self._frame, frame, pose, method)

    def finish(self, result: Result) -> None:
        self._guarded(self._finish, result)

    def _start(self, method: Any, context: MethodContext) -> None:
        rr, rec = self.rr, self.rec
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        rec.log("run", rr.TextLog(f"{self.name}"), static=True)
        i = context.intrinsics
        rec.log(
            "world/camera/image",
            rr.Pinhole(image_from_camera=i.matrix, resolution=[i.width, i.height], camera_xyz=rr.ViewCoordinates.RDF),
            static=True,
        )
        if self.truth is not None and len(self.truth):
            rec.log(
                "world/truth",
                rr.LineStrips3D([self.truth.positions], colors=[COLORS["truth"]], radii=0.03),
                static=True,
            )

    def _frame(self, frame: Frame, pose: np.ndarray, method: Any) -> None:
        rr, rec = self.rr, self.rec
        t = float(frame.timestamp)
        if self._first_stamp is None:
            self._first_stamp = t
        rec.set_time("frame", sequence=frame.index)
        rec.set_time("time", duration=t - self._first_stamp)
        if self._first_stamp >= WALL_CLOCK_AFTER_S:
            rec.set_time("timestamp", timestamp=t)
        pose = np.asarray(pose, dtype=np.float64)
        self._estimate.append(pose[:3, 3].copy())
        if frame.odometry is not None:
            self._odometry.append(np.asarray(frame.odometry)[:3, 3].copy())
        rec.log("world/camera", rr.Transform3D(translation=pose[:3, 3], mat3x3=pose[:3, :3]))
        rec.log("world/camera/image/rgb", rr.Image(frame.rgb).compress(jpeg_quality=80))
        depth_mm = np.rint(np.clip(frame.depth, 0.0, 65.535) * 1000.0).astype(np.uint16)
        rec.log("world/camera/image/depth", rr.DepthImage(depth_mm, meter=1000.0))
        if self.truth is not None and len(self.truth):
            k, gap = nearest_indices(np.array([t]), self.truth.timestamps)
            if gap[0] <= TRUTH_MAX_DIFF:
                error = float(np.linalg.norm(self.truth.positions[k[0]] - pose[:3, 3]))
                rec.log("error/position", rr.Scalars(error))
        if len(self._estimate) % self.every == 1 or self.every == 1:
            self._log_paths()
            self._log_map_chunk(frame, pose)
            self._log_loops(method)

    def _finish(self, result: Result) -> None:
        rr, rec = self.rr, self.rec
        self._log_paths()
        rec.log("world/final", rr.LineStrips3D([result.trajectory.positions], colors=[COLORS["final"]], radii=0.03))
        counts = {k: v for k, v in result.stats.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
        rec.log("run", rr.TextLog("finished: " + json.dumps(counts, sort_keys=True, default=json_default)))

    # pieces ---------------------------------------------------------------------

    def _log_paths(self) -> None:
        """The paths' points since the last call, each batch an entity of its own (from the last
        point drawn, so the segments join): a long run sends each point once, not the whole line
        again and again."""
        for kind, points, radius in (("estimate", self._estimate, 0.03), ("odometry", self._odometry, 0.02)):
            start = max(self._drawn[kind] - 1, 0)
            if len(points) - start < 2:
                continue
            self.rec.log(
                f"world/{kind}/{self._segments[kind]}",
                self.rr.LineStrips3D([np.array(points[start:])], colors=[COLORS[kind]], radii=radius),
            )
            self._segments[kind] += 1
            self._drawn[kind] = len(points)

    def _log_map_chunk(self, frame: Frame, pose: np.ndarray) -> None:
        """A sparse cloud of this frame at its online pose: the map as the method sees it grow."""
        s = self.map_stride
        depth = np.asarray(frame.depth)[::s, ::s]
        rgb = np.asarray(frame.rgb)[::s, ::s]
        i = frame.intrinsics
        v, u = np.mgrid[0 : depth.shape[0], 0 : depth.shape[1]]
        z = depth.astype(np.float64)
        keep = z > 0
        if not keep.any():
            return
        x = (u[keep] * s - i.cx) / i.fx * z[keep]
        y = (v[keep] * s - i.cy) / i.fy * z[keep]
        points = np.column_stack([x, y, z[keep]]) @ pose[:3, :3].T + pose[:3, 3]
        self.rec.log(f"world/map/{self._map_chunks}", self.rr.Points3D(points, colors=rgb[keep], radii=0.03))
        self._map_chunks += 1

    def _log_loops(self, method: Any) -> None:
        """Constraints of the method's pose graph other than odometry, between its nodes' latest
        estimates (planar poses, drawn at the camera's height)."""
        graph = pose_graph(method)
        if graph is None or not self._estimate:
            return
        z = float(self._estimate[-1][2])
        strips, colors = [], []
        for edge in graph.edges:
            if edge.kind == ODOMETRY:
                continue
            a, b = graph.estimate(edge.a), graph.estimate(edge.b)
            strips.append([[a[0], a[1], z], [b[0], b[1], z]])
            colors.append(COLORS.get(edge.kind, COLORS["loop"]))
        if strips:
            self.rec.log("world/loops", self.rr.LineStrips3D(strips, colors=colors, radii=0.04))


def _first_line(err: BaseException) -> str:
    text = str(err).strip()
    return text.splitlines()[0] if text else type(err).__name__
