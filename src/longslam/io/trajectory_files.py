"""Trajectory files: TUM (`t tx ty tz qx qy qz qw`) and KITTI (12 numbers, a 3x4 matrix, a line);
and, read only, EuRoC as ORB-SLAM3 writes it (`SaveTrajectoryEuRoC`: TUM's line with the stamp in
nanoseconds).

KITTI files carry no timestamps: a KITTI trajectory gets the frame index as its timestamp and is
matched to another trajectory by index.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from longslam.core.errors import InputError, TrajectoryError
from longslam.core.geometry import poses_from_tum, tum_from_poses
from longslam.core.textfile import read_bounded_text
from longslam.core.trajectory import Trajectory
from longslam.io.atomic import write_text_atomic
from longslam.io.plain_table import plain_table

TUM, KITTI, EUROC = "tum", "kitti", "euroc"
NANOSECONDS = 1e-9
# A TUM line is about 110 bytes and 100 km about 80 MB: beyond these a file (or stdin) is not a
# trajectory, and reading on would end in a MemoryError (`evaluate /dev/zero SEQ`).
MAX_TRAJECTORY_BYTES = 256 * 10**6
MAX_LINE_BYTES = 4096


def read_trajectory_text(path: str | Path, stream=None, name: str | None = None) -> str:
    """The text of a trajectory file (or of `stream`, stdin), bounded: see `read_bounded_text`."""
    return read_bounded_text(Path(path), "trajectory file", MAX_TRAJECTORY_BYTES, MAX_LINE_BYTES, stream, name)


def _read_rows(path: Path, text: str | None = None) -> list[tuple[int, list[str]]]:
    text = read_trajectory_text(path) if text is None else text
    rows = []
    for number, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if line and not line.startswith("#"):
            rows.append((number, line.replace(",", " ").split()))
    return rows


def _numbers(path: Path, rows: list[tuple[int, list[str]]], width: int, what: str) -> np.ndarray:
    out = np.empty((len(rows), width))
    for i, (number, fields) in enumerate(rows):
        if len(fields) != width:
            raise InputError(f"{path}:{number}: expected {width} numbers ({what}), got {len(fields)}")
        try:
            out[i] = [float(f) for f in fields]
        except ValueError:
            raise InputError(f"{path}:{number}: not a number in {' '.join(fields)!r} (expected {what})") from None
    return out


def detect_format(path: str | Path, text: str | None = None) -> str:
    """'tum' for 8 fields a line, 'kitti' for 12 (of the file, or of `text` read elsewhere)."""
    path = Path(path)
    rows = _read_rows(path, text)
    if not rows:
        raise InputError(f"trajectory file {path} holds no poses")
    width = len(rows[0][1])
    if width == 8:
        return TUM
    if width == 12:
        return KITTI
    raise InputError(
        f"{path}:{rows[0][0]}: {width} fields; expected 8 (TUM: t tx ty tz qx qy qz qw) or 12 (KITTI: 3x4 matrix)"
    )


def _table(path: Path, text: str | None, width: int, what: str) -> np.ndarray:
    text = read_trajectory_text(path) if text is None else text
    table = plain_table(text, width)
    return table if table is not None else _numbers(path, _read_rows(path, text), width, what)


def read_tum(path: str | Path, text: str | None = None) -> Trajectory:
    path = Path(path)
    data = _table(path, text, 8, "t tx ty tz qx qy qz qw")
    if len(data) and np.any(np.linalg.norm(data[:, 4:8], axis=1) < 1e-9):
        bad = int(np.flatnonzero(np.linalg.norm(data[:, 4:8], axis=1) < 1e-9)[0])
        raise TrajectoryError(f"{path}: pose {bad} has a zero quaternion")
    # A copy of the stamps: a view would keep the whole table alive beside the poses.
    return Trajectory(data[:, 0].copy(), poses_from_tum(data[:, 1:8]), source=str(path))


def read_euroc(path: str | Path, text: str | None = None) -> Trajectory:
    """ORB-SLAM3's EuRoC trajectory: `t tx ty tz qx qy qz qw` with t in nanoseconds (spaces or
    commas). Not the EuRoC dataset's own ground-truth CSV, whose quaternion starts with w."""
    path = Path(path)
    data = _table(path, text, 8, "t[ns] tx ty tz qx qy qz qw")
    if len(data) and np.any(np.linalg.norm(data[:, 4:8], axis=1) < 1e-9):
        bad = int(np.flatnonzero(np.linalg.norm(data[:, 4:8], axis=1) < 1e-9)[0])
        raise TrajectoryError(f"{path}: pose {bad} has a zero quaternion")
    return Trajectory(data[:, 0] * NANOSECONDS, poses_from_tum(data[:, 1:8]), source=str(path))


def read_kitti(path: str | Path, text: str | None = None) -> Trajectory:
    path = Path(path)
    data = _table(path, text, 12, "a row-major 3x4 pose matrix")
    poses = np.tile(np.eye(4), (len(data), 1, 1))
    poses[:, :3, :4] = data.reshape(-1, 3, 4)
    return Trajectory(np.arange(len(data), dtype=np.float64), poses, source=str(path))


def read_trajectory(path: str | Path, fmt: str | None = None, text: str | None = None) -> tuple[Trajectory, str]:
    """Read a TUM or KITTI file (format detected unless given; EuRoC only when given), or `text` already read (from
    stdin: `path` then only names it in errors). Returns the trajectory and its format."""
    if text is None:  # read once: a pipe (`<(...)`) cannot be read again after the format is found
        text = read_trajectory_text(path)
    fmt = fmt or detect_format(path, text)
    if fmt == TUM:
        return read_tum(path, text), fmt
    if fmt == KITTI:
        return read_kitti(path, text), fmt
    if fmt == EUROC:
        return read_euroc(path, text), fmt
    raise InputError(f"unknown trajectory format {fmt!r}; valid formats: {TUM}, {KITTI}, {EUROC}")


def format_tum(trajectory: Trajectory) -> str:
    # Nine decimals on the stamp: evo and the TUM tools match stamps, so they must round-trip.
    rows = tum_from_poses(trajectory.poses)
    lines = ["# timestamp tx ty tz qx qy qz qw"]
    lines += [f"{t:.9f} " + " ".join(f"{v:.9f}" for v in row) for t, row in zip(trajectory.timestamps, rows)]
    return "\n".join(lines) + "\n"


def write_tum(path: str | Path, trajectory: Trajectory) -> None:
    write_text_atomic(path, format_tum(trajectory))


def write_kitti(path: str | Path, trajectory: Trajectory) -> None:
    rows = trajectory.poses[:, :3, :4].reshape(-1, 12)
    write_text_atomic(path, "".join(" ".join(f"{v:.9e}" for v in row) + "\n" for row in rows))
