"""Reading a sequence folder, longslam's or a real TUM one, frame by frame."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterator, Sequence
from pathlib import Path

import cv2
import numpy as np

from longslam.core.errors import InputError
from longslam.core.frame import Frame, Intrinsics
from longslam.core.textfile import read_text
from longslam.core.timestamps import associate_indices, match_every
from longslam.core.trajectory import Trajectory
from longslam.io.camera_guess import intrinsics_without_camera_json
from longslam.io.plain_table import plain_table
from longslam.io.sequence.layout import (
    CAMERA,
    DEFAULT_MAX_DIFF,
    DEPTH_LIST,
    DEPTH_SCALE,
    GROUND_TRUTH,
    META,
    ODOMETRY,
    RGB_LIST,
)
from longslam.io.sequence.not_a_sequence import bag_refusal
from longslam.io.trajectory_files import read_tum


class PackedNames(Sequence[str]):
    """Strings held as one array of UTF-8 bytes, not as a Python object each. As lists of str, a
    long route's file names pin the heap of the whole parse around them, even once it is trimmed."""

    def __init__(self, names: Sequence[str] | np.ndarray):
        names = np.asarray(names, dtype=str).reshape(-1)
        # Fixed width: the longest name's bytes per name (NumPy drops the padding on reading).
        self._encoded = np.char.encode(names, "utf-8") if len(names) else np.zeros(0, "S1")

    def __len__(self) -> int:
        return len(self._encoded)

    def __getitem__(self, i):  # type: ignore[override]
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        i = range(len(self))[i]  # negative indices, and IndexError past the end
        return self._encoded[i].decode("utf-8")


def _read_list(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """A TUM image list ('# ...' comments, then 'timestamp filename' lines) as its stamps
    (float64) and file names (str array)."""
    text = read_text(path, "image list", hint=f"a TUM sequence needs {path.name}")
    table = plain_table(text, 2, str)
    if table is not None:
        try:
            stamps = table[:, 0].astype(np.float64)
        except ValueError:
            stamps = None
        if stamps is not None and np.isfinite(stamps).all():
            return stamps, table[:, 1]
    rows = []
    for number, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        fields = line.split()
        if len(fields) != 2:
            raise InputError(f"{path}:{number}: expected 'timestamp filename', got {len(fields)} fields: {line!r}")
        try:
            t = float(fields[0])
        except ValueError:
            raise InputError(f"{path}:{number}: timestamp {fields[0]!r} is not a number") from None
        if not math.isfinite(t):
            raise InputError(f"{path}:{number}: timestamp {fields[0]!r} is not finite")
        rows.append((t, fields[1]))
    if not rows:
        raise InputError(f"{path} lists no images")
    return np.array([t for t, _ in rows], np.float64), np.array([name for _, name in rows], dtype=str)


def _duplicates(stamps: np.ndarray) -> int:
    return len(stamps) - len(np.unique(stamps))


def _pairing_notes(rgb_stamps: np.ndarray, depth_stamps: np.ndarray, paired: int, max_diff: float) -> list[str]:
    notes = []
    for name, stamps in ((RGB_LIST, rgb_stamps), (DEPTH_LIST, depth_stamps)):
        repeated = _duplicates(stamps)
        if repeated:
            notes.append(f"{name} lists {repeated} timestamp{'s' if repeated > 1 else ''} more than once")
    if paired < len(rgb_stamps):
        notes.append(
            f"{len(rgb_stamps) - paired} of {len(rgb_stamps)} colour images in {RGB_LIST} have no depth image "
            f"in {DEPTH_LIST} within {max_diff} s and are left out ({paired} frames)"
        )
    if paired < len(depth_stamps):
        notes.append(
            f"{len(depth_stamps) - paired} of {len(depth_stamps)} depth images in {DEPTH_LIST} are paired "
            f"with no colour image and are not used"
        )
    return notes


def _coverage_notes(frames: np.ndarray, stamps: np.ndarray, max_diff: float, what: str) -> list[str]:
    """How many frames a trajectory file has no pose for (within `max_diff`), if any."""
    if len(stamps) == 0:
        return [f"{what} holds no poses"]
    order = np.sort(stamps)
    k = np.clip(np.searchsorted(order, frames), 1, len(order) - 1) if len(order) > 1 else np.zeros(len(frames), int)
    nearest = np.minimum(np.abs(order[k] - frames), np.abs(order[np.maximum(k - 1, 0)] - frames))
    missing = int(np.count_nonzero(nearest > max_diff))
    notes = []
    if missing:
        notes.append(f"{what} has no pose within {max_diff} s for {missing} of {len(frames)} frames")
    repeated = _duplicates(stamps)
    if repeated:
        notes.append(f"{what} lists {repeated} timestamp{'s' if repeated > 1 else ''} more than once")
    return notes


def _read_json_object(file: Path) -> dict:
    try:
        data = json.loads(file.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise InputError(f"{file} cannot be read as JSON: {err}") from None
    if not isinstance(data, dict):
        raise InputError(f"{file} must hold a JSON object, got {type(data).__name__}")
    return data


def _read_image(path: str | Path, flags: int) -> np.ndarray:
    try:
        data = np.fromfile(path, dtype=np.uint8)
    except FileNotFoundError:
        raise InputError(f"image {path} does not exist") from None
    except OSError as err:
        raise InputError(f"image {path} cannot be read: {err}") from None
    image = cv2.imdecode(data, flags) if data.size else None
    if image is None:
        raise InputError(f"image {path} cannot be decoded (not a valid image file)")
    return image


class SequenceReader:
    """Read a sequence in the TUM RGB-D layout (ours or a real TUM one) as `Frame`s.

    Attributes: `path`, `intrinsics`, `depth_scale`, `max_depth` (None if unknown), `meta`
    ({} without meta.json), `ground_truth` and `odometry` (Trajectory or None), `timestamps`
    (the rgb stamps that have a depth image, ascending). Frames are loaded from disk one at a
    time by `frame(i)` and iteration.
    """

    def __init__(
        self, path: str | Path, max_diff: float = DEFAULT_MAX_DIFF, intrinsics: Sequence[float] | str | None = None
    ):
        # `intrinsics` (fx, fy, cx, cy) replace camera.json's, or stand in for a missing one.
        self._given_intrinsics = intrinsics
        self.path = Path(path)
        self._folder = str(self.path)
        self.max_diff = float(max_diff)
        refusal = bag_refusal(self.path)
        if refusal is not None:
            raise InputError(refusal)
        if not self.path.is_dir():
            what = "is not a folder" if self.path.exists() else "does not exist"
            raise InputError(f"sequence folder {self.path} {what}")

        rgb_stamps, rgb_names = _read_list(self.path / RGB_LIST)
        depth_stamps, depth_names = _read_list(self.path / DEPTH_LIST)
        pairs = associate_indices(rgb_stamps, depth_stamps, self.max_diff)
        if not len(pairs):
            raise InputError(
                f"{self.path}: no rgb image in {RGB_LIST} has a depth image in {DEPTH_LIST} "
                f"within {self.max_diff} s"
            )
        # What the index files leave out, said rather than dropped without a word (as import does).
        self.notes: list[str] = _pairing_notes(rgb_stamps, depth_stamps, len(pairs), self.max_diff)
        self.timestamps = rgb_stamps[pairs[:, 0]]
        self._rgb_files = PackedNames(rgb_names[pairs[:, 0]])
        self._depth_files = PackedNames(depth_names[pairs[:, 1]])
        del rgb_names, depth_names, pairs
        self._check_files_exist()

        self.meta = self._read_meta()
        self.intrinsics, self.depth_scale, self.max_depth = self._read_camera()
        k = self.intrinsics
        if not (0 <= k.cx <= k.width and 0 <= k.cy <= k.height):
            where = "--intrinsics" if self.intrinsics_source.startswith("given") else self.intrinsics_source
            raise InputError(
                f"{where}: principal point (cx, cy) = ({k.cx:g}, {k.cy:g}) lies outside "
                f"the {k.width} x {k.height} image; expected 0 <= cx <= width and 0 <= cy <= height"
            )

        # The truth is read here for its notes, then again when asked for: a method never reads
        # it, and a 10 km route's poses are 9 MB held through the whole run.
        self._ground_truth: Trajectory | None = None
        self._has_ground_truth = (self.path / GROUND_TRUTH).exists()
        if self._has_ground_truth:
            self.notes += _coverage_notes(
                self.timestamps,
                read_tum(self.path / GROUND_TRUTH).timestamps,
                self.max_diff,
                str(self.path / GROUND_TRUTH),
            )
        self.odometry: Trajectory | None = None
        self._odometry_index: np.ndarray | None = None
        if (self.path / ODOMETRY).exists():
            self.odometry = read_tum(self.path / ODOMETRY)
            self._odometry_index = match_every(
                self.timestamps, self.odometry.timestamps, self.max_diff, str(self.path / ODOMETRY)
            )

    @property
    def ground_truth(self) -> Trajectory | None:
        """groundtruth.txt (None without one), read on first use."""
        if self._ground_truth is None and self._has_ground_truth:
            self._ground_truth = read_tum(self.path / GROUND_TRUTH)
        return self._ground_truth

    # setup -----------------------------------------------------------------------

    def _check_files_exist(self) -> None:
        # os.path on str, not pathlib: see `_file`.
        listings: dict[str, set[str]] = {}
        for list_name, names in ((RGB_LIST, self._rgb_files), (DEPTH_LIST, self._depth_files)):
            for i in range(len(names)):
                full = self._file(names, i)
                folder, file_name = os.path.split(full)
                if folder not in listings:
                    try:
                        listings[folder] = set(os.listdir(folder or "."))
                    except OSError:
                        listings[folder] = set()
                if file_name not in listings[folder]:
                    raise InputError(f"image {full} listed in {self.path / list_name} does not exist")

    def _read_meta(self) -> dict:
        file = self.path / META
        return _read_json_object(file) if file.exists() else {}

    def _read_camera(self) -> tuple[Intrinsics, float, float | None]:
        file = self.path / CAMERA
        self.intrinsics_source = str(file)
        if not file.exists() or self._given_intrinsics is not None:
            first = _read_image(self.path / self._rgb_files[0], cv2.IMREAD_COLOR)
            h, w = first.shape[:2]
            intr, self.intrinsics_source = intrinsics_without_camera_json(self.path, w, h, self._given_intrinsics)
            if not file.exists():
                return intr, DEPTH_SCALE, None
            _, scale, max_depth = self._read_camera_json(file)
            return intr, scale, max_depth
        return self._read_camera_json(file)

    def _read_camera_json(self, file: Path) -> tuple[Intrinsics, float, float | None]:
        data = _read_json_object(file)
        intr = Intrinsics.from_dict(data, source=str(file))
        if intr.width <= 0 or intr.height <= 0:
            raise InputError(f"{file}: width and height must be positive, got {intr.width} x {intr.height}")
        for name in ("fx", "fy"):
            value = getattr(intr, name)
            if not math.isfinite(value) or value <= 0:
                raise InputError(f"{file}: field {name} must be a positive number, got {value}")
        for name in ("cx", "cy"):
            if not math.isfinite(getattr(intr, name)):
                raise InputError(f"{file}: field {name} must be a finite number")
        scale = data.get("depth_scale", DEPTH_SCALE)
        if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not math.isfinite(scale) or scale <= 0:
            raise InputError(f"{file}: field depth_scale must be a positive number, got {scale!r}")
        max_depth = data.get("max_depth")
        if max_depth is not None and (
            isinstance(max_depth, bool)
            or not isinstance(max_depth, (int, float))
            or not math.isfinite(max_depth)
            or max_depth <= 0
        ):
            raise InputError(f"{file}: field max_depth must be a positive number of metres or null, got {max_depth!r}")
        return intr, float(scale), None if max_depth is None else float(max_depth)

    # frames ------------------------------------------------------------------------

    def __len__(self) -> int:
        return len(self.timestamps)

    def rgb_path(self, i: int) -> Path:
        return self.path / self._rgb_files[i]

    def depth_path(self, i: int) -> Path:
        return self.path / self._depth_files[i]

    def _file(self, names: PackedNames, i: int) -> str:
        # A str, not a Path: pathlib interns every part of every path it parses, and the table
        # of interned strings never shrinks, so a long sequence's paths would grow the heap.
        return os.path.join(self._folder, names[i])

    def frame(self, i: int) -> Frame:
        """Frame i. Its images are read from disk when the method first looks at them."""
        n = len(self)
        if not -n <= i < n:
            raise IndexError(f"frame index {i} out of range for {self.path} ({n} frames)")
        i = int(i) % n
        odometry = None
        if self.odometry is not None:
            assert self._odometry_index is not None  # matched when odometry.txt was read
            odometry = self.odometry.poses[self._odometry_index[i]].copy()
        return Frame(
            index=i,
            timestamp=float(self.timestamps[i]),
            rgb=lambda: self.read_rgb(i),
            depth=lambda: self.read_depth(i),
            odometry=odometry,
            intrinsics=self.intrinsics,
        )

    def _size_source(self) -> str:
        return str(self.path / CAMERA) if (self.path / CAMERA).exists() else "the first rgb image"

    def read_rgb(self, i: int) -> np.ndarray:
        """Frame i's colour image, (H, W, 3) uint8 RGB."""
        h, w = self.intrinsics.height, self.intrinsics.width
        rgb_file = self._file(self._rgb_files, i)
        bgr = _read_image(rgb_file, cv2.IMREAD_COLOR)
        if bgr.shape[:2] != (h, w):
            raise InputError(
                f"image {rgb_file} is {bgr.shape[1]} x {bgr.shape[0]}, but {self._size_source()} " f"says {w} x {h}"
            )
        return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)

    def read_depth(self, i: int) -> np.ndarray:
        """Frame i's depth, (H, W) float32 metres, 0 where there is no return."""
        h, w = self.intrinsics.height, self.intrinsics.width
        depth_file = self._file(self._depth_files, i)
        raw = _read_image(depth_file, cv2.IMREAD_UNCHANGED)
        if raw.ndim != 2 or raw.dtype != np.uint16:
            raise InputError(
                f"depth image {depth_file} must be single-channel 16-bit, got " f"{raw.dtype} with shape {raw.shape}"
            )
        if raw.shape != (h, w):
            raise InputError(
                f"depth image {depth_file} is {raw.shape[1]} x {raw.shape[0]}, but {self._size_source()} "
                f"says {w} x {h}"
            )
        return (raw.astype(np.float32) / np.float32(self.depth_scale)).astype(np.float32)

    def __getitem__(self, i: int) -> Frame:
        return self.frame(i)

    def __iter__(self) -> Iterator[Frame]:
        for i in range(len(self)):
            yield self.frame(i)
