"""The `command` method: any program that reads a TUM RGB-D folder and writes a trajectory.

`step` writes each frame into a TUM folder (`rgb/`, `depth/` as 16-bit PNG, metres x 5000,
`rgb.txt`, `depth.txt`, and `odometry.txt` when every frame has odometry; never the ground truth)
and returns the pose the run starts from: the program runs only at the end, so the online
trajectory holds that pose. `finish` writes `associations.txt` (and the camera settings file if
the command uses `{settings}`), runs the program in `{output}` as its working directory, with a
timeout, and reads the trajectory it wrote.

Where the files go: `sequence/` (removed once the program ends, unless `keep_sequence`: a run
folder that keeps it holds a sequence, which `--overwrite` then refuses to replace), `program/`
(`{output}`), `settings.yaml` and `program_trajectory.txt` in the run folder
(`MethodContext.output_dir`), or in a temporary folder removed at the end when there is none.
The program's stdout and stderr go to the run's `console.log` (`program.log` in that temporary
folder without one). Relative paths in the command are the program's business, read from
`{output}`; only the program itself is looked up now (on PATH, or against the current folder).

The program's poses are in its own map frame. They are placed in longslam's world by their
first pose: it goes to the odometry pose of its frame (the first odometry pose when the program
reports from the first frame, as most do; the start pose at `camera_height` without odometry),
`T_world_first * inv(T_program_first) * T_program_i`, so the odometry places the map and is not
used again. Poses match frames by stamp (within 0.02 s, one to one; a KITTI file, which has no
stamps, gives one pose per frame in order).

The result's trajectory has a pose for every frame, as every method's: a frame the program gave
no pose for (a keyframe-only trajectory, frames lost) holds the last pose it gave, and frames
before its first hold the start pose, so `trajectory.txt` is scored over the whole route and
charges what the program left out. `program_trajectory.txt` holds only the poses the program
gave (anchored, at their frames' stamps): `longslam evaluate RUN/program_trajectory.txt SEQ`
scores those alone. `stats.json` says how much the program covered: `frames_covered`,
`coverage` (their share of the frames), `program_poses_unmatched`.

A program that cannot start, exits non-zero, is killed by a signal, outlives `timeout` (its
whole process group is killed) or writes no readable trajectory fails the run with a
`MethodError` naming how it ended and the last lines it printed. The program runs as a child of
the run's process, so the run's peak memory, CPU time and CPU wait cover it (the engine measures
the process tree). `MethodSpec.threads` is fixed at 1 whatever the program does: a program with
threads of its own may wait for cores in a study with several jobs, which `cpu_wait_share`
shows. Programs are taken as non-deterministic.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from longslam.core.errors import InputError, LongslamError, MethodError
from longslam.core.frame import Frame
from longslam.core.geometry import CameraMount, anchor, base_to_camera, camera_poses_from_planar, hold_last
from longslam.core.timestamps import one_to_one_nearest
from longslam.core.trajectory import Trajectory
from longslam.io.atomic import write_text
from longslam.io.sequence import DEFAULT_MAX_DIFF, DEPTH_SCALE, SequenceWriter
from longslam.io.sequence.layout import STAMP_DECIMALS
from longslam.io.trajectory_files import EUROC, KITTI, read_euroc, read_kitti, read_tum, write_tum
from longslam.slam import stats
from longslam.slam.api import MethodContext, MethodSpec, Result
from longslam.slam.command.config import METHOD, CommandConfig, command_line, fill, placeholders_of
from longslam.slam.command.files import associations_text, write_settings
from longslam.slam.command.program import last_lines, run_program

SEQUENCE_DIR, OUTPUT_DIR = "sequence", "program"
ASSOCIATIONS = "associations.txt"  # inside the sequence folder
SETTINGS = "settings.yaml"
PROGRAM_TRAJECTORY = "program_trajectory.txt"  # the program's own poses, anchored, beside trajectory.txt
PROGRAM_LOG = "program.log"  # where its output goes when the run has no console.log
DEFAULT_CAMERA_HEIGHT = 1.25  # m, the built-in methods' default, for a start without odometry
MATCH_S = DEFAULT_MAX_DIFF  # 0.02 s, TUM associate.py's: a program pose to a frame
MAX_DEPTH_PNG = 65535 / DEPTH_SCALE  # m, the largest depth a 16-bit PNG at 5000 a metre holds
WHAT = f"method {METHOD!r}"


def resolve_program(word: str) -> str:
    """The program's path as it will be run from `{output}`: a name is looked up on PATH now, a
    relative path made absolute against the current folder. InputError if it is not there."""
    if placeholders_of(word):  # "{output}/prog": a file the run makes, found then or not
        return word
    expanded = os.path.expanduser(word)
    if os.sep not in expanded:
        found = shutil.which(expanded)
        if found is None:
            raise InputError(f"{WHAT}: program {word!r} is not on PATH; give its path, or add its folder to PATH")
        return found
    path = Path(expanded).absolute()
    if not path.is_file():
        raise InputError(f"{WHAT}: program {word!r} does not exist ({path})")
    if not os.access(path, os.X_OK):
        raise InputError(
            f"{WHAT}: program {word!r} is not executable ({path}); chmod +x it, or name its "
            "interpreter first (python3 script.py)"
        )
    return str(path)


class CommandMethod:
    name = METHOD
    images_every_frame = ("rgb", "depth")

    def __init__(self, context: MethodContext, config: CommandConfig = CommandConfig()):
        self.context = context
        self.config = config
        self._words = config.words()
        self._words[0] = resolve_program(self._words[0])
        if context.output_dir is not None:
            self._workdir, self._own_workdir = Path(context.output_dir), False
        else:
            self._workdir, self._own_workdir = Path(tempfile.mkdtemp(prefix="longslam-command-")), True
        self._sequence = self._workdir / SEQUENCE_DIR
        self._output = self._workdir / OUTPUT_DIR
        self._writer: SequenceWriter | None = None
        self._stamps: list[float] = []
        self._odometry: list[np.ndarray | None] = []
        self._start: np.ndarray | None = None
        self._depth_dropped = 0
        self._write_s = 0.0

    # -- the frames ---------------------------------------------------------------------------

    def _camera_height(self) -> float:
        if self.config.camera_height is not None:
            return float(self.config.camera_height)
        first = self._odometry[0] if self._odometry else None
        if first is not None:
            return CameraMount.from_first_pose(first).camera_height
        return DEFAULT_CAMERA_HEIGHT

    def _start_pose(self, frame: Frame) -> np.ndarray:
        if frame.odometry is not None:
            return np.array(frame.odometry, dtype=np.float64)
        # No odometry (a recorded TUM sequence): the robot at the origin, as the built-in methods start.
        height = self.config.camera_height if self.config.camera_height is not None else DEFAULT_CAMERA_HEIGHT
        return camera_poses_from_planar(np.zeros((1, 3)), height)[0]

    def _depth(self, depth: Any) -> np.ndarray:
        """Depth the PNG can hold: NaN, negative and beyond 13.1 m become 0 (no return), counted."""
        depth = np.asarray(depth, dtype=np.float32)
        bad = ~(np.isfinite(depth) & (depth >= 0.0) & (depth <= MAX_DEPTH_PNG))
        if bad.any():
            self._depth_dropped += int(bad.sum())
            depth = np.where(bad, np.float32(0.0), depth)
        return depth

    def _open_writer(self) -> SequenceWriter:
        max_depth = self.context.max_depth
        if max_depth is None or not np.isfinite(max_depth) or not 0.0 < max_depth <= MAX_DEPTH_PNG:
            max_depth = MAX_DEPTH_PNG
        writer = SequenceWriter(
            self._sequence,
            self.context.intrinsics,
            max_depth,
            {"written_by": "longslam's command method, for the program it runs"},
        )
        writer.__enter__()
        return writer

    def step(self, frame: Frame) -> np.ndarray:
        t0 = time.perf_counter()
        if self._writer is None:
            self._writer = self._open_writer()
        self._writer.add(float(frame.timestamp), frame.rgb, self._depth(frame.depth))
        self._write_s += time.perf_counter() - t0
        self._stamps.append(float(frame.timestamp))
        odometry = frame.odometry
        self._odometry.append(None if odometry is None else np.array(odometry, dtype=np.float64))
        if self._start is None:
            self._start = self._start_pose(frame)
        return self._start.copy()

    def _close_writer(self, error: BaseException | None = None) -> None:
        writer, self._writer = self._writer, None
        if writer is None:
            return
        if error is not None:  # the temporary folder goes
            writer.__exit__(type(error), error, error.__traceback__)
            return
        if all(pose is not None for pose in self._odometry):
            writer.set_odometry(Trajectory(np.array(self._stamps), np.array(self._odometry), source="odometry"))
        writer.__exit__(None, None, None)

    # -- the program --------------------------------------------------------------------------

    def _values(self) -> dict[str, Any]:
        k = self.context.intrinsics
        return {
            "sequence": str(self._sequence),
            "output": str(self._output),
            "associations": str(self._sequence / ASSOCIATIONS),
            "settings": str(self._workdir / SETTINGS),
            "fx": float(k.fx),
            "fy": float(k.fy),
            "cx": float(k.cx),
            "cy": float(k.cy),
            "width": int(k.width),
            "height": int(k.height),
            "depth_scale": int(DEPTH_SCALE),
        }

    def _prepare_files(self) -> None:
        texts = [f"{t:.{STAMP_DECIMALS}f}" for t in self._stamps]
        write_text(self._sequence / ASSOCIATIONS, associations_text(texts))
        if self.config.uses("settings"):
            write_settings(self._workdir / SETTINGS, self.context.intrinsics, np.array(self._stamps))
        self._output.mkdir(parents=True, exist_ok=True)

    def _read_trajectory(self, path: Path, output: str) -> Trajectory:
        if not path.is_file():
            left = sorted(p.name for p in self._output.iterdir()) if self._output.is_dir() else []
            shown = ", ".join(left[:8]) + (" ..." if len(left) > 8 else "") if left else "nothing"
            raise MethodError(
                f"{WHAT}: the program exited with status 0 but wrote no trajectory {path} (parameter "
                f"trajectory={self.config.trajectory!r}, relative to {{output}}, its working folder); "
                f"{{output}} holds {shown}; {last_lines(output)}"
            )
        try:
            if self.config.format == EUROC:
                trajectory = read_euroc(path)
            elif self.config.format == KITTI:
                trajectory = read_kitti(path)
            else:
                trajectory = read_tum(path)
        except LongslamError as err:
            raise MethodError(
                f"{WHAT}: the program's trajectory is not a {self.config.format} file as the "
                f"parameter format says: {err}"
            ) from None
        if not len(trajectory):
            raise MethodError(f"{WHAT}: the program's trajectory {path} holds no poses; {last_lines(output)}")
        return trajectory

    def _match(self, trajectory: Trajectory, path: Path) -> tuple[np.ndarray, np.ndarray]:
        """(indices into the program's poses, indices of their frames), one to one, in time order."""
        stamps = np.array(self._stamps)
        if self.config.format == KITTI:
            if len(trajectory) > len(stamps):
                raise MethodError(
                    f"{WHAT}: the program's KITTI trajectory {path} holds {len(trajectory)} poses for "
                    f"{len(stamps)} frames; a KITTI file has one pose per frame, in order"
                )
            index = np.arange(len(trajectory))
            return index, index.copy()
        ours, frames = one_to_one_nearest(trajectory.timestamps, stamps, MATCH_S)
        if not len(ours):
            span = f"{trajectory.timestamps[0]:.6f}..{trajectory.timestamps[-1]:.6f}"
            raise MethodError(
                f"{WHAT}: none of the {len(trajectory)} poses of the program's trajectory {path} is "
                f"within {MATCH_S} s of a frame (its stamps span {span} s, the frames' "
                f"{stamps[0]:.6f}..{stamps[-1]:.6f} s); its stamps must be rgb.txt's, in seconds "
                "(format=euroc for nanoseconds, format=kitti for a file without stamps)"
            )
        return ours, frames

    def finish(self) -> Result:
        if not self._stamps:
            raise InputError(f"{WHAT}: no frames were given")
        try:
            return self._finish()
        finally:
            self._cleanup()

    def _finish(self) -> Result:
        self._close_writer()
        self._prepare_files()
        argv = fill(self._words, self._values())
        log = Path(self.context.console_log) if self.context.console_log else self._workdir / PROGRAM_LOG
        try:
            run = run_program(argv, self._output, log, self.config.timeout, WHAT)
        finally:
            if not self.config.keep_sequence:
                shutil.rmtree(self._sequence, ignore_errors=True)
        path = self._output / self.config.trajectory
        program = self._read_trajectory(path, run.output)
        ours, frames = self._match(program, path)
        poses = program.poses[ours]
        height = self._camera_height()
        if self.config.frame == "robot":
            poses = poses @ base_to_camera(height)
        first = int(frames[0])
        world_first = self._odometry[first] if self._odometry[first] is not None else self._start
        anchored = anchor(poses, world_first)
        stamps = np.array(self._stamps)
        count = len(stamps)
        final = hold_last(count, frames, anchored, self._start)
        if not self._own_workdir:
            write_tum(self._workdir / PROGRAM_TRAJECTORY, Trajectory(stamps[frames], anchored, source="program"))
        uses_odometry = self._odometry[first] is not None
        method_stats = {
            stats.FRAMES: count,
            stats.MAP_BYTES: {},
            "command_line": command_line(argv),
            "program_exit_status": run.exit_status,
            "program_wall_time_s": run.wall_time_s,
            "program_cpu_time_s": run.cpu_time_s,  # the program and the children it waited for
            "program_max_rss_bytes": run.max_rss_bytes,  # its largest single process (the run's peak sums the tree)
            "program_poses": len(program),
            "program_poses_unmatched": len(program) - len(ours),  # no frame within 0.02 s
            "frames_covered": len(frames),  # frames with a pose of the program's; the others hold the last one
            "coverage": len(frames) / count,
            "anchor_frame": first,  # the frame whose pose placed the program's map
            "trajectory_format": self.config.format,
            "pose_frame": self.config.frame,
            "uses_wheel_odometry": "the anchor pose only" if uses_odometry else "no",
            "sequence_write_s": self._write_s,  # writing the frames' PNGs, inside the step times
            "depth_values_dropped": self._depth_dropped,  # NaN, negative or beyond 13.1 m: written as 0
        }
        if self.config.frame == "robot" or not uses_odometry:
            method_stats[stats.CAMERA_HEIGHT] = height
        assert self._start is not None  # `step` placed it at the first frame; `finish` refuses no frames
        online = np.repeat(self._start[None], count, axis=0)
        return Result(
            trajectory=Trajectory(stamps, final, source=METHOD),
            online=Trajectory(stamps, online, source=f"{METHOD} online"),
            stats=method_stats,
        )

    def _cleanup(self) -> None:
        if self._own_workdir:
            shutil.rmtree(self._workdir, ignore_errors=True)

    def close(self) -> None:
        """A run stopped before `finish` returned: the half-written folder goes (`finish` kills the program)."""
        try:
            self._close_writer(InputError("the run stopped"))
        finally:
            self._cleanup()


SPEC = MethodSpec(
    METHOD,
    CommandConfig,
    CommandMethod,
    "any program that reads a TUM RGB-D folder and writes a trajectory",
    # The program may be anything: its threads are its own (threads stays 1, MethodSpec's is
    # static), it runs after the last frame, and nothing says it repeats itself.
    threads=1,
    real_time=False,
    deterministic=False,
    required=("command",),
)
