"""Writing a sequence folder: frame by frame (`SequenceWriter`), or derived from another sequence
with its own odometry (`derive_sequence`); atomically, so no half-written folder remains."""

from __future__ import annotations

import json
import math
import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Literal

import cv2
import numpy as np

import longslam
from longslam.core.errors import InputError
from longslam.core.frame import Intrinsics
from longslam.core.jsonable import json_default
from longslam.core.timestamps import match_every
from longslam.core.trajectory import Trajectory
from longslam.io.atomic import atomic_path, write_bytes, write_text
from longslam.io.overwrite_policy import SEQUENCE, check_not_an_input, check_replaceable, replace_guard
from longslam.io.partials import clean_stale_partials
from longslam.io.sequence.layout import (
    CAMERA,
    DEFAULT_MAX_DIFF,
    DEPTH_DIR,
    DEPTH_LIST,
    DEPTH_SCALE,
    GROUND_TRUTH,
    META,
    ODOMETRY,
    RGB_DIR,
    RGB_LIST,
    STAMP_DECIMALS,
)
from longslam.io.sequence.reader import SequenceReader
from longslam.io.trajectory_files import write_tum


def _stamp_text(t: float) -> str:
    return f"{t:.{STAMP_DECIMALS}f}"


def _meta_json(meta: dict) -> str:
    if not isinstance(meta, dict):
        raise InputError(f"sequence meta must be a dict, got {type(meta).__name__}")
    meta = dict(meta)
    meta.setdefault("longslam_version", longslam.__version__)
    try:
        return json.dumps(meta, indent=2, sort_keys=True, default=json_default) + "\n"
    except (TypeError, ValueError) as err:
        raise InputError(f"sequence meta cannot be written as JSON: {err}") from None


def _list_text(kind: str, stamps: list[str], folder: str) -> str:
    lines = [f"# {kind} images", "# written by longslam", "# timestamp filename"]
    lines += [f"{s} {folder}/{s}.png" for s in stamps]
    return "\n".join(lines) + "\n"


def _check_max_depth(max_depth) -> float:
    try:
        value = float(max_depth)
    except (TypeError, ValueError):
        raise InputError(f"max_depth must be a number of metres, got {max_depth!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise InputError(f"max_depth must be a positive number of metres, got {max_depth!r}")
    if value > 65535 / DEPTH_SCALE:
        raise InputError(
            f"max_depth {value} m cannot be stored in 16-bit depth images scaled by {DEPTH_SCALE:g} "
            f"(largest storable depth {65535 / DEPTH_SCALE:.3f} m)"
        )
    return value


def _refuse_existing(path: Path, overwrite: bool) -> None:
    if not overwrite and (path.exists() or path.is_symlink()):
        raise InputError(f"{path} exists already; pass overwrite=True to replace it")
    check_replaceable(path, SEQUENCE, overwrite)  # overwrite replaces a sequence, nothing else


@contextmanager
def _sequence_folder(path: Path, overwrite: bool) -> Iterator[Path]:
    """A temporary folder beside `path`, renamed to it when the block ends (see `atomic_path`)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    clean_stale_partials(path.parent)  # left by writers that were killed
    with atomic_path(path, overwrite=overwrite, may_replace=replace_guard(SEQUENCE)) as tmp:
        tmp.mkdir()
        yield tmp


def _encode_png(image: np.ndarray, where: str) -> bytes:
    ok, buf = cv2.imencode(".png", image)
    if not ok:
        raise InputError(f"{where}: OpenCV could not encode the image as PNG")
    return buf.tobytes()


def _write_camera(folder: Path, intrinsics: Intrinsics, depth_scale: float, max_depth) -> None:
    data = intrinsics.to_dict()
    data["depth_scale"] = depth_scale
    data["max_depth"] = max_depth
    write_text(folder / CAMERA, json.dumps(data, indent=2) + "\n")


class SequenceWriter:
    """Stream frames into a new sequence folder; it appears at `path` only on success.

    ::

        with SequenceWriter(path, intrinsics, max_depth=8.0, meta={...}) as writer:
            for t, rgb, depth in frames:
                writer.add(t, rgb, depth)
            writer.set_ground_truth(gt)
            writer.set_odometry(odom)

    Each frame goes to disk as soon as it is added (nothing is held in memory but its timestamp).
    Timestamps are written with 6 decimals and must be strictly increasing at that precision.
    Trajectories may be set at any point inside the block; if an odometry is set, every frame
    must have an odometry pose within `max_diff` seconds (checked when the block ends, as the
    reader would). An exception (including KeyboardInterrupt) inside the block removes the
    temporary folder and leaves `path` as it was.
    """

    def __init__(
        self,
        path: str | Path,
        intrinsics: Intrinsics,
        max_depth: float,
        meta: dict,
        overwrite: bool = False,
        max_diff: float = DEFAULT_MAX_DIFF,
    ):
        self.path = Path(path)
        if not isinstance(intrinsics, Intrinsics):
            raise InputError(f"intrinsics must be an Intrinsics, got {type(intrinsics).__name__}")
        self.intrinsics = intrinsics
        self.max_depth = _check_max_depth(max_depth)
        self._meta_text = _meta_json(meta)
        self.overwrite = bool(overwrite)
        self.max_diff = float(max_diff)
        _refuse_existing(self.path, self.overwrite)
        self._tmp: Path | None = None
        self._stamps: list[float] = []
        self._stamp_texts: list[str] = []
        self._ground_truth: Trajectory | None = None
        self._odometry: Trajectory | None = None
        self._done = False

    # context manager ----------------------------------------------------------

    def __enter__(self) -> "SequenceWriter":
        if self._tmp is not None or self._done:
            raise InputError(f"SequenceWriter for {self.path} can be entered only once")
        self._folder_block = _sequence_folder(self.path, self.overwrite)
        self._tmp = self._folder_block.__enter__()
        (self._tmp / RGB_DIR).mkdir()
        (self._tmp / DEPTH_DIR).mkdir()
        return self

    def __exit__(self, exc_type, exc, tb) -> Literal[False]:
        tmp, self._tmp = self._tmp, None
        assert tmp is not None  # entered: `__enter__` made the folder
        self._done = True
        block = self._folder_block
        if exc_type is None:
            try:
                self._finish(tmp)
            except BaseException as err:
                block.__exit__(type(err), err, err.__traceback__)
                raise
        block.__exit__(exc_type, exc, tb)  # renames the folder, or removes it after an error
        return False

    @property
    def temp_path(self) -> Path | None:
        """The temporary folder being written (None outside the `with` block)."""
        return self._tmp

    def __len__(self) -> int:
        return len(self._stamps)

    # adding data ---------------------------------------------------------------

    def _folder(self, what: str) -> Path:
        if self._tmp is None:
            raise InputError(f"SequenceWriter.{what} for {self.path} must be called inside its `with` block")
        return self._tmp

    def add(self, timestamp: float, rgb: np.ndarray, depth: np.ndarray) -> None:
        """Write one frame: rgb (H, W, 3) uint8 RGB, depth (H, W) float metres (0 = no return)."""
        folder = self._folder("add")
        try:
            t = float(timestamp)
        except (TypeError, ValueError):
            raise InputError(f"frame timestamp must be a number, got {timestamp!r}") from None
        if not math.isfinite(t) or t < 0:
            raise InputError(f"frame timestamp must be finite and >= 0, got {timestamp!r}")
        text = _stamp_text(t)
        if self._stamps and float(text) <= float(self._stamp_texts[-1]):
            raise InputError(
                f"frame timestamp {t!r} (written {text}) does not follow the previous frame's "
                f"{self._stamp_texts[-1]}; timestamps must be strictly increasing at "
                f"{STAMP_DECIMALS} decimals"
            )
        where = f"frame {len(self._stamps)} (t={text})"
        h, w = self.intrinsics.height, self.intrinsics.width
        rgb = np.asarray(rgb)
        depth = np.asarray(depth)
        if rgb.dtype != np.uint8:
            raise InputError(f"{where}: rgb must be uint8, got {rgb.dtype}")
        if rgb.shape != (h, w, 3):
            raise InputError(
                f"{where}: rgb must have shape (height, width, 3) = ({h}, {w}, 3) "
                f"per the intrinsics, got {rgb.shape}"
            )
        if depth.dtype not in (np.float32, np.float64):
            raise InputError(
                f"{where}: depth must be float32 metres, got {depth.dtype} "
                f"(convert scaled integer depth to metres first)"
            )
        if depth.shape != (h, w):
            raise InputError(
                f"{where}: depth must have shape (height, width) = ({h}, {w}) per the " f"intrinsics, got {depth.shape}"
            )
        if not np.all(np.isfinite(depth)):
            raise InputError(f"{where}: depth holds NaN or inf; use 0 for pixels with no return")
        if depth.size and depth.min() < 0:
            raise InputError(f"{where}: depth holds negative values (min {depth.min():.4g} m)")
        limit = 65535 / DEPTH_SCALE
        if depth.size and depth.max() > limit:
            raise InputError(
                f"{where}: depth {depth.max():.4g} m exceeds the largest storable depth "
                f"{limit:.3f} m (16-bit, scale {DEPTH_SCALE:g})"
            )
        depth_png = np.rint(depth.astype(np.float64) * DEPTH_SCALE).astype(np.uint16)
        bgr = cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2BGR)
        write_bytes(folder / RGB_DIR / f"{text}.png", _encode_png(bgr, where))
        write_bytes(folder / DEPTH_DIR / f"{text}.png", _encode_png(depth_png, where))
        self._stamps.append(t)
        self._stamp_texts.append(text)

    def set_ground_truth(self, traj: Trajectory) -> None:
        self._folder("set_ground_truth")
        if not isinstance(traj, Trajectory):
            raise InputError(f"ground truth must be a Trajectory, got {type(traj).__name__}")
        self._ground_truth = traj

    def set_odometry(self, traj: Trajectory) -> None:
        self._folder("set_odometry")
        if not isinstance(traj, Trajectory):
            raise InputError(f"odometry must be a Trajectory, got {type(traj).__name__}")
        self._odometry = traj

    # finishing -----------------------------------------------------------------

    def _finish(self, tmp: Path) -> None:
        if not self._stamps:
            raise InputError(f"sequence {self.path}: no frames were added")
        stamps = np.array([float(s) for s in self._stamp_texts])
        if self._odometry is not None:
            match_every(stamps, self._odometry.timestamps, self.max_diff, f"odometry for {self.path}")
            write_tum(tmp / ODOMETRY, self._odometry)
        if self._ground_truth is not None:
            write_tum(tmp / GROUND_TRUTH, self._ground_truth)
        write_text(tmp / RGB_LIST, _list_text("color", self._stamp_texts, RGB_DIR))
        write_text(tmp / DEPTH_LIST, _list_text("depth", self._stamp_texts, DEPTH_DIR))
        _write_camera(tmp, self.intrinsics, DEPTH_SCALE, self.max_depth)
        write_text(tmp / META, self._meta_text)


def derive_sequence(
    source: str | Path,
    path: str | Path,
    odometry: Trajectory,
    meta: dict,
    overwrite: bool = False,
    max_diff: float = DEFAULT_MAX_DIFF,
) -> None:
    """A new sequence at `path` with the frames of `source` and its own odometry and meta.

    Images are hard-linked (copied where the filesystem refuses links, e.g. across devices);
    rgb.txt, depth.txt, camera.json and groundtruth.txt are copied. The odometry must have a pose
    within `max_diff` of every frame. Written atomically, like `SequenceWriter`.
    """
    source, path = Path(source), Path(path)
    if not isinstance(odometry, Trajectory):
        raise InputError(f"odometry must be a Trajectory, got {type(odometry).__name__}")
    reader = SequenceReader(source, max_diff=max_diff)
    check_not_an_input(path, {"source sequence": source}, "new sequence")
    meta_text = _meta_json(meta)
    _refuse_existing(path, overwrite)
    match_every(reader.timestamps, odometry.timestamps, max_diff, f"odometry for {path}")

    with _sequence_folder(path, overwrite) as tmp:
        can_link = True
        for name in sorted(set(reader._rgb_files) | set(reader._depth_files)):
            src, dst = source / name, tmp / name
            dst.parent.mkdir(parents=True, exist_ok=True)
            if can_link:
                try:
                    os.link(src, dst)
                    continue
                except OSError:
                    can_link = False
            shutil.copy2(src, dst)
        for name in (RGB_LIST, DEPTH_LIST, CAMERA, GROUND_TRUTH):
            if (source / name).is_file():
                shutil.copy2(source / name, tmp / name)
        write_tum(tmp / ODOMETRY, odometry)
        write_text(tmp / META, meta_text)
