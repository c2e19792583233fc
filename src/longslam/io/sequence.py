"""RGB-D sequences on disk in the TUM RGB-D layout.

A sequence folder holds::

    rgb/<t>.png        8-bit colour images
    depth/<t>.png      16-bit depth, metres x depth_scale (5000), 0 = no return
    rgb.txt            TUM list: '# ...' header lines, then 'timestamp filename' lines
    depth.txt          the same for the depth images
    groundtruth.txt    TUM trajectory, camera-in-world (optional: real TUM test sequences lack it)
    odometry.txt       TUM trajectory of the noisy odometry, camera-in-world (longslam only)
    camera.json        width, height, fx, fy, cx, cy, depth_scale, max_depth (longslam only)
    meta.json          free-form provenance: world, route, noise level, seed, version (longslam only)

Real TUM sequences (no camera.json, no odometry.txt, rgb and depth stamps that differ by a few
milliseconds) read as well: rgb and depth images are associated by nearest timestamp as TUM's
`associate.py` does.

Writing is atomic: `SequenceWriter` and `derive_sequence` build the sequence in a hidden temporary
sibling folder and rename it to its final name only when everything has been written, so an
interrupted run never leaves a folder that a later run would take as a complete sequence.
"""

from __future__ import annotations

import json
import math
import os
import shutil
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

import cv2
import numpy as np

import longslam
from longslam.errors import InputError
from longslam.jsonable import json_default
from longslam.textfile import read_text
from longslam.frame import Frame, Intrinsics
from longslam.io.atomic import atomic_path, write_bytes, write_text
from longslam.io.camera_guess import intrinsics_without_camera_json
from longslam.io.partials import clean_stale_partials
from longslam.io.trajectory_files import read_tum, write_tum
from longslam.timestamps import associate_lists, match_every
from longslam.trajectory import Trajectory

DEPTH_SCALE = 5000.0  # TUM: a 16-bit depth value of 5000 is one metre
DEFAULT_MAX_DIFF = 0.02  # seconds; TUM associate.py's default
STAMP_DECIMALS = 6

RGB_DIR, DEPTH_DIR = "rgb", "depth"
RGB_LIST, DEPTH_LIST = "rgb.txt", "depth.txt"
GROUND_TRUTH, ODOMETRY = "groundtruth.txt", "odometry.txt"
CAMERA, META = "camera.json", "meta.json"



# --------------------------------------------------------------------------- helpers


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


@contextmanager
def _sequence_folder(path: Path, overwrite: bool) -> Iterator[Path]:
    """A temporary folder beside `path`, renamed to it when the block ends (see `atomic_path`)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    clean_stale_partials(path.parent)  # left by writers that were killed
    with atomic_path(path, overwrite=overwrite) as tmp:
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


# --------------------------------------------------------------------------- writing


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

    def __exit__(self, exc_type, exc, tb) -> bool:
        tmp, self._tmp = self._tmp, None
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
            raise InputError(
                f"SequenceWriter.{what} for {self.path} must be called inside its `with` block"
            )
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
                f"{where}: depth must have shape (height, width) = ({h}, {w}) per the "
                f"intrinsics, got {depth.shape}"
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
    if path.resolve() == source.resolve():
        raise InputError(f"derive_sequence: the new sequence {path} is the source itself")
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


# --------------------------------------------------------------------------- reading


def _read_list(path: Path) -> list[tuple[float, str]]:
    """A TUM image list: '# ...' comments, then 'timestamp filename' lines."""
    text = read_text(path, "image list", hint=f"a TUM sequence needs {path.name}")
    rows = []
    for number, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        fields = line.split()
        if len(fields) != 2:
            raise InputError(
                f"{path}:{number}: expected 'timestamp filename', got {len(fields)} fields: {line!r}"
            )
        try:
            t = float(fields[0])
        except ValueError:
            raise InputError(f"{path}:{number}: timestamp {fields[0]!r} is not a number") from None
        if not math.isfinite(t):
            raise InputError(f"{path}:{number}: timestamp {fields[0]!r} is not finite")
        rows.append((t, fields[1]))
    if not rows:
        raise InputError(f"{path} lists no images")
    return rows


def _read_image(path: Path, flags: int) -> np.ndarray:
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

    def __init__(self, path: str | Path, max_diff: float = DEFAULT_MAX_DIFF, intrinsics: Sequence[float] | str | None = None):
        # `intrinsics` (fx, fy, cx, cy) replace camera.json's, or stand in for a missing one.
        self._given_intrinsics = intrinsics
        self.path = Path(path)
        self.max_diff = float(max_diff)
        if not self.path.is_dir():
            what = "is not a folder" if self.path.exists() else "does not exist"
            raise InputError(f"sequence folder {self.path} {what}")

        rgb_rows = _read_list(self.path / RGB_LIST)
        depth_rows = _read_list(self.path / DEPTH_LIST)
        pairs = associate_lists([t for t, _ in rgb_rows], [t for t, _ in depth_rows], self.max_diff)
        if not pairs:
            raise InputError(
                f"{self.path}: no rgb image in {RGB_LIST} has a depth image in {DEPTH_LIST} "
                f"within {self.max_diff} s"
            )
        self.timestamps = np.array([rgb_rows[i][0] for i, _ in pairs], dtype=np.float64)
        self._rgb_files = [rgb_rows[i][1] for i, _ in pairs]
        self._depth_files = [depth_rows[j][1] for _, j in pairs]
        self._check_files_exist()

        self.meta = self._read_meta()
        self.intrinsics, self.depth_scale, self.max_depth = self._read_camera()

        self.ground_truth: Trajectory | None = None
        if (self.path / GROUND_TRUTH).exists():
            self.ground_truth = read_tum(self.path / GROUND_TRUTH)
        self.odometry: Trajectory | None = None
        self._odometry_index: np.ndarray | None = None
        if (self.path / ODOMETRY).exists():
            self.odometry = read_tum(self.path / ODOMETRY)
            self._odometry_index = match_every(
                self.timestamps, self.odometry.timestamps, self.max_diff, str(self.path / ODOMETRY)
            )

    # setup -----------------------------------------------------------------------

    def _check_files_exist(self) -> None:
        listings: dict[Path, set[str]] = {}
        for list_name, names in ((RGB_LIST, self._rgb_files), (DEPTH_LIST, self._depth_files)):
            for name in names:
                full = self.path / name
                folder = full.parent
                if folder not in listings:
                    try:
                        listings[folder] = set(os.listdir(folder))
                    except OSError:
                        listings[folder] = set()
                if full.name not in listings[folder]:
                    raise InputError(
                        f"image {full} listed in {self.path / list_name} does not exist"
                    )

    def _read_meta(self) -> dict:
        file = self.path / META
        if not file.exists():
            return {}
        try:
            meta = json.loads(file.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
            raise InputError(f"{file} cannot be read as JSON: {err}") from None
        if not isinstance(meta, dict):
            raise InputError(f"{file} must hold a JSON object, got {type(meta).__name__}")
        return meta

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
        try:
            data = json.loads(file.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
            raise InputError(f"{file} cannot be read as JSON: {err}") from None
        if not isinstance(data, dict):
            raise InputError(f"{file} must hold a JSON object, got {type(data).__name__}")
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
        if (
            isinstance(scale, bool)
            or not isinstance(scale, (int, float))
            or not math.isfinite(scale)
            or scale <= 0
        ):
            raise InputError(f"{file}: field depth_scale must be a positive number, got {scale!r}")
        max_depth = data.get("max_depth")
        if max_depth is not None and (
            isinstance(max_depth, bool)
            or not isinstance(max_depth, (int, float))
            or not math.isfinite(max_depth)
            or max_depth <= 0
        ):
            raise InputError(
                f"{file}: field max_depth must be a positive number of metres or null, got {max_depth!r}"
            )
        return intr, float(scale), None if max_depth is None else float(max_depth)

    # frames ------------------------------------------------------------------------

    def __len__(self) -> int:
        return len(self.timestamps)

    def rgb_path(self, i: int) -> Path:
        return self.path / self._rgb_files[i]

    def depth_path(self, i: int) -> Path:
        return self.path / self._depth_files[i]

    def frame(self, i: int) -> Frame:
        n = len(self)
        if not -n <= i < n:
            raise IndexError(f"frame index {i} out of range for {self.path} ({n} frames)")
        i = int(i) % n
        h, w = self.intrinsics.height, self.intrinsics.width
        size_source = str(self.path / CAMERA) if (self.path / CAMERA).exists() else "the first rgb image"

        rgb_file = self.rgb_path(i)
        bgr = _read_image(rgb_file, cv2.IMREAD_COLOR)
        if bgr.shape[:2] != (h, w):
            raise InputError(
                f"image {rgb_file} is {bgr.shape[1]} x {bgr.shape[0]}, but {size_source} "
                f"says {w} x {h}"
            )
        rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)

        depth_file = self.depth_path(i)
        raw = _read_image(depth_file, cv2.IMREAD_UNCHANGED)
        if raw.ndim != 2 or raw.dtype != np.uint16:
            raise InputError(
                f"depth image {depth_file} must be single-channel 16-bit, got "
                f"{raw.dtype} with shape {raw.shape}"
            )
        if raw.shape != (h, w):
            raise InputError(
                f"depth image {depth_file} is {raw.shape[1]} x {raw.shape[0]}, but {size_source} "
                f"says {w} x {h}"
            )
        depth = (raw.astype(np.float32) / np.float32(self.depth_scale)).astype(np.float32)

        odometry = None
        if self.odometry is not None:
            odometry = self.odometry.poses[self._odometry_index[i]].copy()
        return Frame(
            index=i,
            timestamp=float(self.timestamps[i]),
            rgb=rgb,
            depth=depth,
            odometry=odometry,
            intrinsics=self.intrinsics,
        )

    def __getitem__(self, i: int) -> Frame:
        return self.frame(i)

    def __iter__(self) -> Iterator[Frame]:
        for i in range(len(self)):
            yield self.frame(i)
