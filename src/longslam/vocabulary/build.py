"""From a sequence's (or a route's) frames to a DBoW2 vocabulary file that ORB-SLAM3 loads.

Each chosen frame is one training image: its ORB descriptors, extracted as ORB-SLAM3 extracts
them, are the image's features for the tree's k-means and for the words' IDF weights.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from longslam.core.errors import InputError
from longslam.core.progress import bar as tqdm
from longslam.io.sequence import SequenceReader
from longslam.sim.camera import CameraSettings
from longslam.sim.routes import Route
from longslam.sim.simulate import rendered_sequence
from longslam.vocabulary.dbow2 import loader_size_problem, write_vocabulary
from longslam.vocabulary.tree import Vocabulary, build_tree

# ORB-SLAM3's extractor settings (Examples/RGB-D/TUM1.yaml and ORBextractor.cc): 8 levels a
# factor 1.2 apart, FAST at threshold 20 and 7 where 20 finds nothing, 31-pixel patches with a
# 19-pixel border. OpenCV's ORB computes the same descriptor (the same 256 point pairs, on the
# image blurred 7 x 7 with sigma 2); only the spreading of keypoints over the image differs.
ORB_LEVELS = 8
ORB_SCALE = 1.2
INI_FAST = 20
MIN_FAST = 7
EDGE_THRESHOLD = 19
PATCH_SIZE = 31
CELL = 35  # ORB-SLAM3's FAST cell, in pixels of each pyramid level
# As the orbslam3 method's `features` (ORBextractor.nFeatures): OpenCV's ORB allocates for the
# number asked, and 100,000,000 ended in std::bad_alloc.
MAX_FEATURES = 20000


def check_features(features: int) -> None:
    """ORB features per frame: a whole number from 1 to MAX_FEATURES."""
    if isinstance(features, bool) or not isinstance(features, (int, np.integer)) or not 1 <= features <= MAX_FEATURES:
        raise InputError(
            f"--features must be a whole number from 1 to {MAX_FEATURES} ORB features per frame "
            f"(as ORB-SLAM3's nFeatures), got {features!r}"
        )


class OrbExtractor:
    """ORB keypoints and 32-byte descriptors of grey images, with ORB-SLAM3's settings.

    ORB-SLAM3 runs FAST at `INI_FAST` in each 35-pixel cell of each pyramid level and falls back
    to `MIN_FAST` in a cell where that finds no corner, so low-contrast walls still give features.
    OpenCV's ORB takes one threshold; here the keypoints at `MIN_FAST` fill the cells that the
    keypoints at `INI_FAST` leave empty, strongest first, up to `features`.
    """

    def __init__(self, features: int = 1000):
        check_features(features)
        self.features = int(features)

        def orb(threshold: int) -> cv2.ORB:
            return cv2.ORB_create(
                nfeatures=self.features,
                scaleFactor=ORB_SCALE,
                nlevels=ORB_LEVELS,
                edgeThreshold=EDGE_THRESHOLD,
                patchSize=PATCH_SIZE,
                fastThreshold=threshold,
            )

        self._strict, self._loose = orb(INI_FAST), orb(MIN_FAST)

    @staticmethod
    def _cell(keypoint: cv2.KeyPoint) -> tuple[int, int, int]:
        scale = ORB_SCALE**keypoint.octave
        return keypoint.octave, int(keypoint.pt[0] / scale // CELL), int(keypoint.pt[1] / scale // CELL)

    def descriptors(self, gray: np.ndarray) -> np.ndarray:
        """(n, 32) uint8 descriptors of a grey (H, W) uint8 image; n may be 0."""
        keypoints = list(self._strict.detect(gray, None))
        if len(keypoints) < self.features:
            taken = {self._cell(kp) for kp in keypoints}
            extra = sorted(
                (kp for kp in self._loose.detect(gray, None) if self._cell(kp) not in taken),
                key=lambda kp: -kp.response,
            )
            keypoints += extra[: self.features - len(keypoints)]
        if not keypoints:
            return np.zeros((0, 32), dtype=np.uint8)
        _, descriptors = self._strict.compute(gray, keypoints)
        return np.zeros((0, 32), dtype=np.uint8) if descriptors is None else descriptors


def chosen_frames(total: int, every: int = 1, max_frames: int | None = None) -> np.ndarray:
    """Indices of every `every`-th frame, thinned evenly to at most `max_frames`."""
    if isinstance(every, bool) or not isinstance(every, (int, np.integer)) or every < 1:
        raise InputError(f"--frames-every must be a whole number >= 1, got {every!r}")
    if max_frames is not None and (
        isinstance(max_frames, bool) or not isinstance(max_frames, (int, np.integer)) or max_frames < 1
    ):
        raise InputError(f"--max-frames must be a whole number >= 1, got {max_frames!r}")
    frames = np.arange(0, total, every)
    if max_frames is not None and len(frames) > max_frames:
        frames = frames[np.linspace(0, len(frames) - 1, max_frames).round().astype(int)]
    return frames


def sequence_descriptors(
    sequence: str | Path,
    features: int = 1000,
    every: int = 1,
    max_frames: int | None = None,
    progress: bool = True,
) -> list[np.ndarray]:
    """ORB descriptors of the chosen frames of a sequence folder, one array per frame."""
    reader = SequenceReader(sequence)
    extractor = OrbExtractor(features)
    frames = chosen_frames(len(reader), every, max_frames)
    out = []
    for i in tqdm(frames, desc="ORB features", unit="frame", disable=not progress, leave=False):
        gray = cv2.cvtColor(reader.read_rgb(int(i)), cv2.COLOR_RGB2GRAY)  # ORB-SLAM3 converts RGB alike
        out.append(extractor.descriptors(gray))
    return out


def check_tree_size(k: int, levels: int) -> None:
    """k and L as the DBoW2 text loader accepts them (k <= 20, 1 <= L <= 10), k >= 2 to branch,
    and a full tree of them small enough for the loader to reserve room for (k^L words: 10^7 at
    k = 10, 20^5 at k = 20; see `loader_size_problem`)."""
    for name, value, low, high in (("--k", k, 2, 20), ("--levels", levels, 1, 10)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not low <= value <= high:
            raise InputError(
                f"{name} must be a whole number in {low}..{high} (ORB-SLAM3's loader's bounds), got {value!r}"
            )
    problem = loader_size_problem(int(k), int(levels))
    if problem is not None:
        raise InputError(f"--k {k} --levels {levels}: {problem}; choose a smaller --k or --levels")


def vocabulary_from_descriptors(
    images: list[np.ndarray],
    k: int = 10,
    levels: int = 5,
    seed: int = 0,
    progress: bool = True,
) -> Vocabulary:
    """The vocabulary tree of these training images' descriptors, reproducible from `seed`."""
    check_tree_size(k, levels)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"--seed must be a whole number >= 0, got {seed!r}")
    total = sum(len(image) for image in images)
    if total == 0:
        raise InputError(f"the {len(images)} frames gave no ORB features (blank or textureless images?)")
    with tqdm(
        total=total, desc="vocabulary tree", unit="desc", unit_scale=True, disable=not progress, leave=False
    ) as bar:
        return build_tree(images, k, levels, np.random.default_rng(seed), progress=bar.update)


@dataclass(frozen=True)
class BuildSummary:
    path: Path
    frames: int
    descriptors: int
    words: int
    nodes: int
    bytes: int
    seconds: float


def rendered_route(route: Route, camera: CameraSettings = CameraSettings(), progress: bool = True) -> Path:
    """The route's rendered frames in the render cache (rendered first if not cached): the
    same frames `longslam simulate` gives a sequence of the route with this camera."""
    return rendered_sequence(route, camera, progress=progress)


def check_output(out: str | Path, overwrite: bool = False) -> Path:
    """Refuse, before any work, an --out that cannot be written or would be replaced unasked."""
    from longslam.io.overwrite_policy import VOCABULARY, check_output_file_free

    out = Path(out)
    if out.is_dir():
        raise InputError(f"--out {out} is a folder; expected a file path (e.g. voc.txt)")
    if not out.absolute().parent.is_dir():
        raise InputError(f"--out {out}: the folder {out.absolute().parent} does not exist")
    check_output_file_free(out, overwrite, "--out", VOCABULARY)  # nor a FIFO, a device or the user's file
    return out


def build_vocabulary_file(
    sequence: str | Path,
    out: str | Path,
    k: int = 10,
    levels: int = 5,
    seed: int = 0,
    features: int = 1000,
    every: int = 1,
    max_frames: int | None = None,
    overwrite: bool = False,
    progress: bool = True,
) -> BuildSummary:
    """Build a vocabulary from a sequence folder's frames and write it to `out` atomically."""
    check_tree_size(k, levels)
    check_features(features)
    out = check_output(out, overwrite)
    from longslam.io.overwrite_policy import check_not_an_input

    # --overwrite replaces a vocabulary file, never a file of the input sequence (its rgb.txt, say).
    check_not_an_input(out, {"input sequence": sequence}, "--out")
    start = time.perf_counter()
    images = sequence_descriptors(sequence, features, every, max_frames, progress)
    vocabulary = vocabulary_from_descriptors(images, k, levels, seed, progress)
    write_vocabulary(vocabulary, out, overwrite=overwrite)
    return BuildSummary(
        out,
        len(images),
        sum(len(i) for i in images),
        len(vocabulary.words),
        vocabulary.nodes,
        out.stat().st_size,
        time.perf_counter() - start,
    )
