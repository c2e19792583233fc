"""What the front end keeps of every frame for its final smoother, in flat arrays.

A frame's factors (its online pose, wheel step and sigmas, constant-velocity step, scan factor,
visual step, the filter's biases) as a Python object holding seven small numpy arrays would cost
several times their data in headers. Here they are one row of 40 doubles (320 bytes) in chunks of
4,096 rows (`slam/rows.py`), read back as the same `FrameRecord` values, so the smoother's graph
is the same to the bit.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from longslam.slam.graph.factors import WheelStep
from longslam.slam.rows import CHUNK, Rows

# Column layout of a row: (first column, width) of each part, and its "present" flag's column.
POSE = (0, 3)
WHEEL, WHEEL_ON = (4, 4), 3  # forward, lateral, yaw, moving
SIGMAS, SIGMAS_ON = (9, 3), 8
CV, CV_ON = (13, 3), 12
SCAN, SCAN_ON = (17, 13), 16  # anchor frame, measurement (3), information (9)
VISUAL, VISUAL_ON = (31, 6), 30  # step (3), its sigmas (3)
BIAS, BIAS_ON = (38, 2), 37
WIDTH = 40


@dataclass
class FrameRecord:
    wheel: WheelStep | None
    wheel_sigmas: np.ndarray | None
    cv_step: np.ndarray | None  # constant-velocity prediction used without wheels
    scan: tuple[int, np.ndarray, np.ndarray] | None  # anchor frame, relative measurement, body information
    visual: tuple[np.ndarray, np.ndarray] | None = None  # step from the previous frame, its stds
    bias: np.ndarray | None = None  # the online filter's wheel biases after this frame


class FrameStore:
    """Rows of frames, appended in order; `store[k]` is frame k's `FrameRecord` (a copy: write
    one back with `store[k] = record`), `store.poses[k]` its online pose."""

    def __init__(self) -> None:
        self._rows = Rows((WIDTH,), CHUNK)
        self.poses = _Poses(self)

    def __len__(self) -> int:
        return len(self._rows)

    def _row(self, k: int) -> np.ndarray:
        return self._rows.row(k)

    def pose_span(self, first: int, stop: int) -> np.ndarray:
        """The online poses of frames first..stop-1, (stop - first, 3)."""
        return self._rows.span(first, stop)[:, POSE[0] : POSE[0] + 3]

    def append(self, pose: np.ndarray, record: FrameRecord) -> None:
        row = np.zeros(WIDTH)
        row[POSE[0] : POSE[0] + 3] = pose
        self._write(row, record)
        self._rows.append(row)

    def __setitem__(self, k: int, record: FrameRecord) -> None:
        self._write(self._row(k), record)

    @staticmethod
    def _write(row: np.ndarray, record: FrameRecord) -> None:
        row[3:] = 0.0

        def put(part: tuple[int, int], flag: int, values) -> None:
            row[flag] = 1.0
            row[part[0] : part[0] + part[1]] = np.concatenate(
                [np.ravel(np.asarray(v, dtype=np.float64)) for v in values]
            )

        if record.wheel is not None:
            w = record.wheel
            put(WHEEL, WHEEL_ON, [w.forward, w.lateral, w.yaw, float(w.moving)])
        if record.wheel_sigmas is not None:
            put(SIGMAS, SIGMAS_ON, [record.wheel_sigmas])
        if record.cv_step is not None:
            put(CV, CV_ON, [record.cv_step])
        if record.scan is not None:
            anchor, measurement, information = record.scan
            put(SCAN, SCAN_ON, [float(anchor), measurement, information])
        if record.visual is not None:
            put(VISUAL, VISUAL_ON, [record.visual[0], record.visual[1]])
        if record.bias is not None:
            put(BIAS, BIAS_ON, [record.bias])

    def __getitem__(self, k: int) -> FrameRecord:
        row = self._row(k)

        def part(span: tuple[int, int]) -> np.ndarray:
            return row[span[0] : span[0] + span[1]].copy()

        wheel = None
        if row[WHEEL_ON]:
            f, lat, yaw, moving = part(WHEEL)
            wheel = WheelStep(float(f), float(lat), float(yaw), bool(moving))
        scan = None
        if row[SCAN_ON]:
            values = part(SCAN)
            scan = (int(values[0]), values[1:4], values[4:13].reshape(3, 3))
        visual = None
        if row[VISUAL_ON]:
            values = part(VISUAL)
            visual = (values[:3], values[3:])
        return FrameRecord(
            wheel,
            part(SIGMAS) if row[SIGMAS_ON] else None,
            part(CV) if row[CV_ON] else None,
            scan,
            visual,
            part(BIAS) if row[BIAS_ON] else None,
        )

    def __iter__(self) -> Iterator[FrameRecord]:
        return (self[k] for k in range(len(self)))

    @property
    def nbytes(self) -> int:
        return self._rows.nbytes


class _Poses:
    """The online poses of a `FrameStore`, as a read-only sequence of (3,) arrays."""

    def __init__(self, store: FrameStore) -> None:
        self._store = store

    def __len__(self) -> int:
        return len(self._store)

    def __getitem__(self, k: int) -> np.ndarray:
        return self._store._row(k)[POSE[0] : POSE[0] + 3].copy()

    def __iter__(self) -> Iterator[np.ndarray]:
        return (self[k] for k in range(len(self)))

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        out = np.array([self[k] for k in range(len(self))]).reshape(-1, 3)
        return out if dtype is None else out.astype(dtype)
