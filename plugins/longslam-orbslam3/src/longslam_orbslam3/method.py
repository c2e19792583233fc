"""The `orbslam3` method: ORB-SLAM3 in RGB-D mode, frames in, poses out.

It uses only longslam's public method API (`longslam.slam.api`): the engine sends ORB-SLAM3's
console to the run's `console.log` (`MethodContext.console_log`), counts the CPU time of its
threads (`process_cpu_time_s`), and calls `close` if a run stops early.

ORB-SLAM3 sees the camera images and depth only; the wheel odometry places its first map in the
building (the first odometry pose, as every longslam method starts) and is not used again.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from longslam.core.errors import InputError
from longslam.core.frame import Frame
from longslam.core.geometry import camera_poses_from_planar, poses_from_tum
from longslam.core.trajectory import Trajectory
from longslam.slam import stats
from longslam.slam.api import Event, MethodContext, MethodSpec, Result
from longslam_orbslam3.anchoring import TRACKED, MapAnchors, final_poses
from longslam_orbslam3.config import OrbSlam3Config
from longslam_orbslam3.console_log import ConsoleFollower, read_counts
from longslam_orbslam3.settings_file import DEPTH_MAP_FACTOR, fps_from_stamps, settings_yaml
from longslam_orbslam3.vocabulary import resolve_vocabulary

SETTINGS_FILE = "orbslam3.yaml"
SAVED_TRAJECTORY = "orbslam3_trajectory_euroc.txt"  # ORB-SLAM3's own, its largest map
SAVED_KEYFRAMES = "orbslam3_keyframes_euroc.txt"
APT_LIBRARIES = "libgl1 libegl1 libopengl0 libsm6 libice6 libx11-6 libxext6"


def _import_pyorbslam3() -> Any:
    try:
        import pyorbslam3
    except ImportError as err:
        raise InputError(
            f"method 'orbslam3' needs the pyorbslam3 package and its system libraries ({err}); install them with "
            f"`apt-get install {APT_LIBRARIES}` and `pip install pyorbslam3==0.1.1`"
        ) from None
    return pyorbslam3


def _thread_ticks(exclude: set[str] = frozenset()) -> dict[str, int]:
    """CPU ticks used so far by each thread of this process (Linux), but those in `exclude`."""
    ticks = {}
    for tid in os.listdir("/proc/self/task"):
        if tid in exclude:
            continue
        try:
            with open(f"/proc/self/task/{tid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except OSError:  # the thread ended meanwhile
            continue
        ticks[tid] = int(fields[11]) + int(fields[12])  # utime + stime
    return ticks


def _read_euroc(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """ORB-SLAM3's EuRoC trajectory: stamp in ns, tx ty tz qx qy qz qw (camera in map)."""
    if not path.is_file() or path.stat().st_size == 0:
        return np.zeros(0), np.zeros((0, 4, 4))
    rows = np.loadtxt(path, ndmin=2)
    return rows[:, 0] * 1e-9, poses_from_tum(rows[:, 1:8])


# Measured with pyorbslam3 on the demo route: 64 x 48 images stop tracking in ORB-SLAM3's
# extractor with the C++ error "vector::_M_default_append" at 8 pyramid levels and segfault at 1 to
# 3; 160 x 120 tracks every frame at the default 8. Smaller images are refused with a message.
MIN_SHORT_SIDE = 120


def _check_image_size(width: int, height: int) -> None:
    if min(width, height) < MIN_SHORT_SIDE:
        raise InputError(
            f"method 'orbslam3': {width} x {height} images are too small for ORB-SLAM3 (it crashes on 64 x 48 and "
            f"tracks from 160 x 120); give a camera at least {MIN_SHORT_SIDE} pixels on its short side"
        )


def _no_map_note(frames: int, anchors: MapAnchors) -> str:
    if not anchors.anchors:
        return (f"ORB-SLAM3 tracked none of the {frames} frames and made no map (too few ORB features, or no "
                "depth?); every pose is held at the start pose")
    return (f"ORB-SLAM3 lost tracking before its map had 10 keyframes, reset it and made no map after; "
            f"{anchors.frames_untracked} of {frames} frames hold the last tracked pose")


class OrbSlam3Method:
    name = "orbslam3"
    images_every_frame = ("rgb", "depth")

    def __init__(self, context: MethodContext, config: OrbSlam3Config = OrbSlam3Config()):
        self.context = context
        self.config = config
        _check_image_size(context.intrinsics.width, context.intrinsics.height)
        self._pos = _import_pyorbslam3()
        self._vocabulary, self._vocabulary_info = resolve_vocabulary(config.vocabulary)
        if context.output_dir is not None:
            self._workdir, self._own_workdir = Path(context.output_dir), False
        else:
            self._workdir, self._own_workdir = Path(tempfile.mkdtemp(prefix="longslam-orbslam3-")), True
        self._log_start = self._log_size()
        self._slam: Any = None
        self._pending: Frame | None = None  # the first frame, tracked once the second gives the rate
        self._anchors: MapAnchors | None = None
        self._stamps: list[float] = []
        self._online: list[np.ndarray] = []
        self._tracked_points = 0
        self._map_changes = 0
        self._fps = 0.0
        self._load_time = 0.0
        self._clock: tuple[float, float] | None = None  # (wall time, stamp) pacing starts from
        self._paced_s = 0.0
        self._system_threads: set[str] = set()
        self._console = ConsoleFollower(context.console_log, self._log_start)
        self._frames: list[int] = []  # each step's frame index
        self._console_events: list[Event] = []

    # -- the run ------------------------------------------------------------------------------

    def _log_size(self) -> int:
        log = self.context.console_log
        return os.path.getsize(log) if log and os.path.exists(log) else 0

    def _start_pose(self, frame: Frame) -> np.ndarray:
        if frame.odometry is not None:
            return np.array(frame.odometry, dtype=np.float64)
        # No odometry (a recorded TUM sequence): the robot at the origin, as the built-in methods start.
        return camera_poses_from_planar(np.zeros((1, 3)), self.config.camera_height)[0]

    def _start_system(self, fps: float) -> None:
        self._fps = fps
        settings = self._workdir / SETTINGS_FILE
        settings.write_text(settings_yaml(self.context.intrinsics, self.config, fps, self.context.max_depth))
        t0 = time.perf_counter()
        try:
            self._slam = self._pos.Slam(self._vocabulary, str(settings), self._pos.Sensor.RGBD, use_viewer=False)
        except (MemoryError, ValueError, RuntimeError) as err:  # what its loader throws gets through the bindings
            raise InputError(f"method 'orbslam3': ORB-SLAM3 did not start with vocabulary {self._vocabulary} "
                             f"({type(err).__name__}: {str(err)[:200]})") from None
        self._load_time = time.perf_counter() - t0
        # Threads alive once the system runs (its mapping and loop closing among them): a later one
        # is a global bundle adjustment (see _wait_for_global_ba).
        self._system_threads = set(os.listdir("/proc/self/task"))

    def _wait_for_turn(self, stamp: float) -> None:
        if self.config.pace <= 0.0:
            return
        now = time.perf_counter()
        if self._clock is None:
            self._clock = (now, stamp)
            return
        due = self._clock[0] + (stamp - self._clock[1]) / self.config.pace
        if due > now:
            time.sleep(due - now)
            self._paced_s += due - now

    def _track(self, frame: Frame) -> np.ndarray:
        self._wait_for_turn(float(frame.timestamp))
        depth = np.asarray(frame.depth, dtype=np.float32) * np.float32(DEPTH_MAP_FACTOR)
        result = self._slam.track_rgbd(np.ascontiguousarray(frame.rgb), depth, float(frame.timestamp))
        state = result.state.name
        if self._slam.map_changed():
            self._map_changes += 1
        self._tracked_points += int(result.num_tracked_points)
        stamp = float(frame.timestamp)
        for kind, line in self._console.new_events():
            self._console_events.append(Event(kind, frame.index, frame.index, stamp, stamp, line))
        return self._anchors.update(state, result.pose_wc if state in TRACKED else None)

    def step(self, frame: Frame) -> np.ndarray:
        if self._anchors is None:
            self._anchors = MapAnchors(self._start_pose(frame))
        self._stamps.append(float(frame.timestamp))
        self._frames.append(frame.index)
        if self._slam is None and self._pending is None:
            # The first frame's pose is the start pose whatever ORB-SLAM3 makes of it: a map
            # begins at the identity, and an untracked frame holds the start.
            self._pending = frame
            pose = self._anchors.start.copy()
            self._online.append(pose)
            return pose
        if self._slam is None:
            self._start_system(fps_from_stamps(np.array(self._stamps)))
            self._online[0] = self._track(self._pending)
            self._pending = None
        pose = self._track(frame)
        self._online.append(pose)
        return pose

    # -- the end ------------------------------------------------------------------------------

    def _wait_for_global_ba(self) -> float:
        """ORB-SLAM3 1.0's Shutdown does not wait for the global bundle adjustment a loop closure
        starts. It runs in a thread of its own, made after the system's threads: wait while such
        a thread works (or the console says a BA runs), until `gba_wait` runs out. Its build in
        pyorbslam3 0.1.1 prints "*Loop detected" but not the BA's start and end, so the thread is
        what tells. Keyframes still queued for loop detection are dropped, as Shutdown drops them."""
        t0 = time.perf_counter()
        ticks = _thread_ticks(exclude=self._system_threads)
        while time.perf_counter() - t0 < self.config.gba_wait:
            running = read_counts(self.context.console_log, self._log_start).global_ba_running
            if not ticks and not running:
                break
            time.sleep(0.25)
            now = _thread_ticks(exclude=self._system_threads)
            working = any(now.get(tid, 0) > used for tid, used in ticks.items()) or set(now) - set(ticks)
            if not working and not running:
                break
            ticks = now
        return time.perf_counter() - t0

    def _shutdown(self) -> None:
        if self._slam is not None and not self._slam.is_shutdown():
            self._slam.shutdown()

    def close(self) -> None:
        self._shutdown()
        self._slam = None
        if self._own_workdir:
            shutil.rmtree(self._workdir, ignore_errors=True)

    def finish(self) -> Result:
        if not self._stamps:
            raise InputError("method 'orbslam3': no frames were given")
        if self._slam is None:  # a one-frame sequence: ORB-SLAM3 needs a second frame for its rate
            self._start_system(10.0)
            self._online[0] = self._track(self._pending)
            self._pending = None
        waited = self._wait_for_global_ba()
        self._shutdown()
        last_frame, last_t = self._frames[-1], self._stamps[-1]  # what its threads printed after the last frame
        self._console_events += [Event(kind, last_frame, last_frame, last_t, last_t, line)
                                 for kind, line in self._console.new_events()]
        console = read_counts(self.context.console_log, self._log_start).counts
        # Each map began at a tracked frame (a segment of the anchors); a map reset after an early
        # loss empties its map. With no map holding a keyframe, ORB-SLAM3 1.0's savers index the
        # keyframes of an empty map: a segfault (or "Invalid argument"), so they are not called.
        maps = max(len(self._anchors.anchors) - console["map_resets"], 0)
        saved_stamps, saved_poses, keyframes = np.zeros(0), np.zeros((0, 4, 4)), 0
        if maps:
            trajectory_file, keyframe_file = self._workdir / SAVED_TRAJECTORY, self._workdir / SAVED_KEYFRAMES
            self._slam.save_trajectory_euroc(str(trajectory_file))
            self._slam.save_keyframe_trajectory_euroc(str(keyframe_file))
            saved_stamps, saved_poses = _read_euroc(trajectory_file)
            keyframes = len(_read_euroc(keyframe_file)[0])
        stamps = np.array(self._stamps)
        online = np.array(self._online)
        final, from_saved = final_poses(online, stamps, self._anchors, saved_stamps, saved_poses)
        frames = len(stamps)
        events = run_events(self._anchors.segment_of_frame, np.array(self._frames), stamps, self._console_events)
        losses = [e for e in events if e.kind == "tracking_lost"]
        notes = []
        if not maps:
            notes.append(_no_map_note(frames, self._anchors))
        method_stats = {
            stats.FRAMES: frames,
            stats.NODES: keyframes,
            stats.LOOPS_ACCEPTED: console["loops"],
            stats.MAP_BYTES: {},
            "tracking_states": dict(sorted(self._anchors.states.items())),
            "frames_untracked": self._anchors.frames_untracked,  # online pose held (not OK)
            # Stretches of untracked frames (events.csv has each, with its frames): the longest
            # in seconds, from the first untracked frame to the first tracked one after it.
            "tracking_lost_intervals": len(losses),
            "tracking_lost_longest_s": max((_loss_seconds(e, stamps) for e in losses), default=0.0),
            "frames_in_final": from_saved,  # the rest of the final trajectory is the online pose
            "maps": maps,  # maps that hold keyframes at the end
            "maps_started": len(self._anchors.anchors),  # a new one after each loss it did not recover from
            "maps_created": console["maps_created"],
            "map_resets": console["map_resets"],
            "map_merges": console["merges"],
            "relocalizations": console["relocalizations"],
            "map_changes": self._map_changes,
            "global_ba": {"started": console["global_ba_started"], "finished": console["global_ba_finished"],
                          "stopped": console["global_ba_stopped"], "waited_s": waited},
            "keyframes_in_final_map": keyframes,
            "tracked_points_mean": self._tracked_points / frames,
            "camera_fps": self._fps,
            "pace": self.config.pace,
            "paced_wait_s": self._paced_s,  # spent waiting for the next frame's time (in the step times)
            "vocabulary": self._vocabulary_info,
            "vocabulary_load_s": self._load_time,
            "uses_wheel_odometry": "first pose only",
            stats.NOTES: notes,
        }
        self._slam = None
        if self._own_workdir:
            shutil.rmtree(self._workdir, ignore_errors=True)
        return Result(
            trajectory=Trajectory(stamps, final, source="orbslam3"),
            online=Trajectory(stamps, online, source="orbslam3 online"),
            stats=method_stats,
            events=events,
        )


def _loss_seconds(loss: Event, stamps: np.ndarray) -> float:
    """How long tracking was lost: to the next frame's stamp (the first tracked again), or to the
    last frame's plus one frame's time at the end of the run."""
    after = stamps[stamps > loss.last_t]
    end = after[0] if len(after) else loss.last_t + (float(np.median(np.diff(stamps))) if len(stamps) > 1 else 0.0)
    return float(end - loss.first_t)


def run_events(segment_of_frame: list[int], frames: np.ndarray, stamps: np.ndarray,
               console_events: list[Event]) -> list[Event]:
    """The run's events in frame order: each stretch of untracked frames (after the first map
    began), each new map after the first, and what the console reported (loops, merges...)."""
    segments = np.asarray(segment_of_frame, dtype=int)
    events = list(console_events)
    tracked = np.flatnonzero(segments >= 0)
    if len(tracked):
        lost = segments < 0
        lost[: tracked[0]] = False  # before the first map: starting up, not lost
        edges = np.diff(np.concatenate([[0], lost.astype(int), [0]]))
        for first, end in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)):
            events.append(Event("tracking_lost", int(frames[first]), int(frames[end - 1]), float(stamps[first]),
                                float(stamps[end - 1]), f"{end - first} frames"))
        starts = np.flatnonzero(np.diff(np.concatenate([[segments[tracked[0]]], segments[tracked]])) > 0)
        for k in starts:
            i = tracked[k]
            events.append(Event("new_map", int(frames[i]), int(frames[i]), float(stamps[i]), float(stamps[i]),
                                f"map {segments[i] + 1}"))
    return sorted(events, key=lambda e: (e.first_frame, e.kind))


def prepare(config: OrbSlam3Config) -> None:
    """Build longslam's default vocabulary into the cache now, if the runs will use it, so that
    building it (a minute, 300 MB) is in no run's time or peak memory."""
    resolve_vocabulary(config.vocabulary)


SPEC = MethodSpec("orbslam3", OrbSlam3Config, OrbSlam3Method,
                  "ORB-SLAM3 1.0 in RGB-D mode (pyorbslam3): visual only, the wheels place its first map",
                  # Tracking, local mapping and loop closing work at once (a global bundle
                  # adjustment adds a fourth); frames come at the sequence's rate; threads race.
                  prepare=prepare, threads=3, real_time=True, deterministic=False)
