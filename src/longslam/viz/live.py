"""A run shown live in a rerun viewer, or recorded to a .rrd file (`longslam run ... --viz`).

An observer of the run engine (`run/observer.py`): it sees each frame and the pose the method
returned, and reads a method's pose graph (`slam.api.pose_graph`, part of the method interface) for its loop
constraints; the methods know nothing of it. rerun (the optional extra `longslam[viz]`) is
imported only here, when a view is asked for.

Entities (timelines `frame` and `time`, world z up):

    world/truth             the true trajectory (the sequence's ground truth), once
    world/estimate          the method's online trajectory so far
    world/odometry          the wheel odometry so far
    world/loops             the method's graph constraints other than odometry, as lines
    world/map/<n>           a sparse coloured cloud of every `every`-th frame at its online pose
    world/camera            the current camera pose; world/camera/image: its pinhole, with
    world/camera/image/rgb  the current colour image and
    world/camera/image/depth  the current depth (millimetres)
    error/position          the online estimate's distance to the true pose (m)
    world/final             the final trajectory, at the end
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

from longslam.errors import InputError
from longslam.frame import Frame
from longslam.io.atomic import rename_no_replace
from longslam.io.partials import partial_path
from longslam.slam.api import MethodContext, Result
from longslam.slam.api import pose_graph
from longslam.slam.graph import ODOMETRY
from longslam.timestamps import nearest_indices
from longslam.trajectory import Trajectory

VIEWER = "viewer"  # --viz without a file: spawn (or join) a viewer on this machine
COLORS = {"truth": (60, 200, 60), "estimate": (230, 60, 40), "odometry": (120, 120, 120),
          "final": (40, 90, 230), "loop": (250, 200, 0), "registration": (180, 60, 220)}
TRUTH_MAX_DIFF = 0.02  # s: the true pose compared with each frame's estimate


def require_rerun() -> Any:
    try:
        import rerun
    except ImportError:
        raise InputError("--viz needs rerun: pip install 'longslam[viz]' (or the version pinned in requirements.lock)") from None
    return rerun


def find_viewer() -> str:
    """The rerun viewer's executable: on PATH, or beside this Python (a virtual environment that is
    not activated has it in its bin/ only). InputError if there is none, before any work."""
    import shutil

    found = shutil.which("rerun") or shutil.which("rerun", path=str(Path(sys.executable).parent))
    if found is None:
        raise InputError("--viz: the rerun viewer (the `rerun` command of rerun-sdk) is not on PATH nor beside "
                         f"{sys.executable}; install it (pip install 'longslam[viz]'), or record to a file: --viz run.rrd")
    return found


VIEWER_PORT = 9876  # rerun's default: spawn() joins a viewer already listening there


def _viewer_listening(port: int = VIEWER_PORT) -> bool:
    import socket

    try:
        with socket.create_connection(("127.0.0.1", port), timeout=0.5):
            return True
    except OSError:
        return False


def check_viewer() -> str | None:
    """The viewer to start, or None to join one already running; InputError if neither can be:
    without a display a spawned viewer dies at once and the run would stream to nobody, forever."""
    if _viewer_listening():
        return None
    viewer = find_viewer()
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise InputError("--viz: there is no display to show the rerun viewer on (DISPLAY and WAYLAND_DISPLAY are "
                         "unset) and no viewer is running; record to a file instead (--viz run.rrd) and open it "
                         "with `rerun run.rrd` where there is a screen")
    return viewer


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
    if (path.exists() or path.is_symlink()) and not overwrite:
        raise InputError(f"--viz {target} exists already; choose another file or pass --overwrite")


class LiveView:
    """Streams a run to rerun. Use as a context manager; a .rrd file appears only when complete."""

    images_every_frame = ("rgb", "depth")  # shown every frame: the engine decodes them ahead

    def __init__(self, target: str, name: str, truth: Trajectory | None = None, every: int = 10, map_stride: int = 8,
                 overwrite: bool = False):
        check_target(target, overwrite)
        self.rr = require_rerun()
        self.target = target
        self.overwrite = overwrite
        self.name = name
        self.truth = truth
        self.every = max(int(every), 1)
        self.map_stride = max(int(map_stride), 1)
        self._tmp: Path | None = None
        self.rec = self.rr.RecordingStream("longslam", recording_id=name)
        if target == VIEWER:
            try:
                viewer = check_viewer()
                if viewer is None:
                    self.rec.connect_grpc()
                else:
                    self.rr.spawn(executable_path=viewer, recording=self.rec)
            except RuntimeError as err:
                first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
                raise InputError(f"--viz: the rerun viewer could not be started ({first}); "
                                 "record to a file instead: --viz run.rrd") from None
        else:
            path = Path(target)
            self._tmp = partial_path(path)
            self.rec.save(self._tmp)
        self._estimate: list[np.ndarray] = []
        self._odometry: list[np.ndarray] = []
        self._map_chunks = 0

    def __enter__(self) -> "LiveView":
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        self.rec.flush()
        self.rec.disconnect()
        if self._tmp is not None:
            if exc_type is None:
                if self.overwrite:
                    os.replace(self._tmp, self.target)
                else:  # a file another process wrote meanwhile is kept
                    try:
                        rename_no_replace(self._tmp, self.target)
                    except FileExistsError:
                        self._tmp.unlink()
                        raise InputError(f"--viz {self.target} was written by another process while this run "
                                         "went on; it was left as it is (pass --overwrite to replace it)") from None
            elif self._tmp.exists():
                self._tmp.unlink()
        return False

    # the observer ----------------------------------------------------------------

    def start(self, method: Any, context: MethodContext) -> None:
        rr, rec = self.rr, self.rec
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        rec.log("run", rr.TextLog(f"{self.name}"), static=True)
        i = context.intrinsics
        rec.log("world/camera/image", rr.Pinhole(image_from_camera=i.matrix, resolution=[i.width, i.height],
                                                 camera_xyz=rr.ViewCoordinates.RDF), static=True)
        if self.truth is not None and len(self.truth):
            rec.log("world/truth", rr.LineStrips3D([self.truth.positions], colors=[COLORS["truth"]], radii=0.03), static=True)

    def frame(self, frame: Frame, pose: np.ndarray, method: Any) -> None:
        rr, rec = self.rr, self.rec
        rec.set_time("frame", sequence=frame.index)
        rec.set_time("time", duration=frame.timestamp)
        pose = np.asarray(pose, dtype=np.float64)
        self._estimate.append(pose[:3, 3].copy())
        if frame.odometry is not None:
            self._odometry.append(np.asarray(frame.odometry)[:3, 3].copy())
        rec.log("world/camera", rr.Transform3D(translation=pose[:3, 3], mat3x3=pose[:3, :3]))
        rec.log("world/camera/image/rgb", rr.Image(frame.rgb).compress(jpeg_quality=80))
        depth_mm = np.rint(np.clip(frame.depth, 0.0, 65.535) * 1000.0).astype(np.uint16)
        rec.log("world/camera/image/depth", rr.DepthImage(depth_mm, meter=1000.0))
        if self.truth is not None and len(self.truth):
            k, gap = nearest_indices(np.array([frame.timestamp]), self.truth.timestamps)
            if gap[0] <= TRUTH_MAX_DIFF:
                error = float(np.linalg.norm(self.truth.positions[k[0]] - pose[:3, 3]))
                rec.log("error/position", rr.Scalars(error))
        if len(self._estimate) % self.every == 1 or self.every == 1:
            self._log_paths()
            self._log_map_chunk(frame, pose)
            self._log_loops(method)

    def finish(self, result: Result) -> None:
        rr, rec = self.rr, self.rec
        self._log_paths()
        rec.log("world/final", rr.LineStrips3D([result.trajectory.positions], colors=[COLORS["final"]], radii=0.03))
        counts = {k: v for k, v in result.stats.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
        rec.log("run", rr.TextLog(f"finished: {counts}"))

    # pieces ---------------------------------------------------------------------

    def _log_paths(self) -> None:
        rr, rec = self.rr, self.rec
        if len(self._estimate) > 1:
            rec.log("world/estimate", rr.LineStrips3D([np.array(self._estimate)], colors=[COLORS["estimate"]], radii=0.03))
        if len(self._odometry) > 1:
            rec.log("world/odometry", rr.LineStrips3D([np.array(self._odometry)], colors=[COLORS["odometry"]], radii=0.02))

    def _log_map_chunk(self, frame: Frame, pose: np.ndarray) -> None:
        """A sparse cloud of this frame at its online pose: the map as the method sees it grow."""
        s = self.map_stride
        depth = np.asarray(frame.depth)[::s, ::s]
        rgb = np.asarray(frame.rgb)[::s, ::s]
        i = frame.intrinsics
        v, u = np.mgrid[0:depth.shape[0], 0:depth.shape[1]]
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
