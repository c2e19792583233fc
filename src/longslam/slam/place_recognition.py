"""Place recognition shared by the SLAM methods: an incremental bag of visual words and PnP
verification of a loop-closure hypothesis.

Follows RTAB-Map's design (see reference/anchors.md): the dictionary grows as the robot sees new
texture (Kp/IncrementalDictionary), at most Kp/MaxFeatures = 500 words per image, candidates are
ranked by a tf-idf similarity, and a hypothesis is accepted only if PnP RANSAC on the candidate's
depth points finds Vis/MinInliers = 20 inliers.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import scipy.sparse as sp

from longslam.core.errors import InputError
from longslam.core.frame import Intrinsics
from longslam.core.geometry import invert, rigid_transform, xyyaw_from_pose
from longslam.slam.features import DESCRIPTOR_BYTES, Features

_MATCH_CHUNK = 1 << 17

# How the dictionary finds a descriptor's nearest word:
# - "bruteforce": OpenCV's BFMatcher over every word (exact; the cost grows with the dictionary);
# - "flat": faiss's exact binary index (the same answers up to ties, faster on a large dictionary);
# - "hnsw": faiss's HNSW graph over the words (approximate: the nearest word is missed now and
#   then, which founds a near-duplicate word; the cost grows with the log of the dictionary).
WORD_INDEXES = ("bruteforce", "flat", "hnsw")
HNSW_NEIGHBOURS = 16  # graph degree M
# The search breadths. At 32 / 40 the word search was a quarter of the wheel-only keyframe
# method's time on paper-300m; at 16 / 20 it costs half that. A word missed now and then founds a
# near-duplicate word, and a loop hypothesis rests on many words, so ATE moves by chance rather
# than by trend (CHANGELOG's Measured history, 2026-12-06: the seeds and figures).
HNSW_EF_CONSTRUCTION = 20
HNSW_EF_SEARCH = 16


def _faiss_index(kind: str):
    import faiss

    # One thread: a multi-threaded HNSW build is not deterministic, and the methods run one per
    # core already.
    faiss.omp_set_num_threads(1)
    bits = 8 * DESCRIPTOR_BYTES
    if kind == "flat":
        return faiss.IndexBinaryFlat(bits)
    index = faiss.IndexBinaryHNSW(bits, HNSW_NEIGHBOURS)
    index.hnsw.efConstruction = HNSW_EF_CONSTRUCTION
    index.hnsw.efSearch = HNSW_EF_SEARCH
    return index


def hamming_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n, 32) x (m, 32) uint8 descriptors -> (n, m) Hamming distances (int32)."""
    # XOR 64 bits at a time: 4 words per descriptor instead of 32 bytes.
    a64 = np.ascontiguousarray(a, dtype=np.uint8).view(np.uint64)
    b64 = np.ascontiguousarray(b, dtype=np.uint8).view(np.uint64)
    x = np.bitwise_xor(a64[:, None, :], b64[None, :, :])
    return np.bitwise_count(x).sum(axis=2, dtype=np.int32)


def _check_descriptors(descriptors: np.ndarray) -> np.ndarray:
    descriptors = np.asarray(descriptors)
    if descriptors.size == 0:
        return np.zeros((0, DESCRIPTOR_BYTES), np.uint8)
    if descriptors.ndim != 2 or descriptors.shape[1] != DESCRIPTOR_BYTES or descriptors.dtype != np.uint8:
        raise InputError(
            f"descriptors must be (N, {DESCRIPTOR_BYTES}) uint8, got {descriptors.shape} {descriptors.dtype}"
        )
    return np.ascontiguousarray(descriptors)


class Vocabulary:
    """Incremental visual-word dictionary with an inverted index over the nodes in working memory.

    A descriptor joins the nearest word if it is within `max_distance` bits, otherwise it founds
    a new word. Word ids are never reused. `forget_unused` takes the words no indexed node holds
    out of the search index (faiss kinds), as RTAB-Map's dictionary drops the words of nodes
    that left working memory: the index then stays the size of working memory's words instead
    of growing with the route, and a node brought back from long-term memory quantises its
    descriptors afresh.
    """

    def __init__(self, max_distance: int = 40, max_words_per_image: int = 500, index: str = "hnsw"):
        if not 0 <= max_distance <= 8 * DESCRIPTOR_BYTES:
            raise InputError(f"max_distance must be in [0, 256] bits, got {max_distance}")
        if max_words_per_image <= 0:
            raise InputError(f"max_words_per_image must be positive, got {max_words_per_image}")
        if index not in WORD_INDEXES:
            raise InputError(f"vocabulary index must be one of {', '.join(WORD_INDEXES)}, got {index!r}")
        self.max_distance = int(max_distance)
        self.max_words_per_image = int(max_words_per_image)
        self._words = np.zeros((1024, DESCRIPTOR_BYTES), np.uint8)  # grown by doubling
        self._n_words = 0
        self._matcher = cv2.BFMatcher(cv2.NORM_HAMMING)
        self._index_kind = index
        self._index = None if index == "bruteforce" else _faiss_index(index)
        self._index_words = np.zeros(0, np.int64)  # word id of each row of the faiss index
        # Bumped whenever the words or their search index change: a search's answer holds until then.
        self._dictionary_version = 0
        # (version, descriptors, nearest word, distance) of the latest search: a method that queries
        # an image and then adds it searches the dictionary once.
        self._last_search: tuple[int, np.ndarray, np.ndarray, np.ndarray] | None = None
        self.index_rebuilds = 0
        # node id -> (unique word ids, counts): the node's bag of words.
        self._bags: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._df = np.zeros(1024, np.int64)  # how many nodes in working memory hold each word
        self._matrix: sp.csr_matrix | None = None  # nodes x words term frequencies, rebuilt lazily
        self._row_ids: np.ndarray = np.zeros(0, np.int64)
        # With the matrix: its columns (a query reads a few words' columns) and each word's idf
        # and each node's tf-idf norm, which change only with the nodes indexed. Made per query,
        # they cost time in proportion to every word and node held: on a long route most of a query.
        self._columns: sp.csc_matrix | None = None
        self._idf: np.ndarray | None = None
        self._norms: np.ndarray | None = None

    # --- dictionary -------------------------------------------------------------------------
    @property
    def n_words(self) -> int:
        return self._n_words

    @property
    def words(self) -> np.ndarray:
        return self._words[: self._n_words]

    @property
    def nodes(self) -> list[int]:
        return list(self._bags)

    def __contains__(self, node_id: int) -> bool:
        return node_id in self._bags

    def __len__(self) -> int:
        return len(self._bags)

    @property
    def nbytes(self) -> int:
        bags = sum(w.nbytes + c.nbytes for w, c in self._bags.values())
        return int(self._words[: self._n_words].nbytes + self._df[: self._n_words].nbytes + bags)

    def _nearest(self, descriptors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nearest word and its distance for each descriptor (-1, 257 with an empty dictionary)."""
        last = self._last_search
        if last is not None and last[0] == self._dictionary_version and np.array_equal(last[1], descriptors):
            return last[2].copy(), last[3].copy()
        word, dist = self._search(descriptors)
        self._last_search = (self._dictionary_version, descriptors.copy(), word.copy(), dist.copy())
        return word, dist

    def _search(self, descriptors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = len(descriptors)
        # Words may exist with none left in the index (`forget_unused`).
        if self._n_words == 0 or n == 0 or (self._index is not None and self._index.ntotal == 0):
            return np.full(n, -1, np.int64), np.full(n, 257, np.int64)
        if self._index is not None:
            dist, row = self._index.search(np.ascontiguousarray(descriptors), 1)
            row, dist = row[:, 0], dist[:, 0].astype(np.int64)
            found = row >= 0
            return np.where(found, self._index_words[np.maximum(row, 0)], -1), np.where(found, dist, 257)
        word = np.full(n, -1, np.int64)
        dist = np.full(n, 257, np.int64)
        # BFMatcher refuses train sets of 2**18 rows or more, so a long route's dictionary is
        # searched in chunks. Brute force is exact; an approximate index (FLANN LSH) would be
        # the next step if dictionaries of millions of words become a bottleneck.
        for start in range(0, self._n_words, _MATCH_CHUNK):
            chunk = self._words[start : min(start + _MATCH_CHUNK, self._n_words)]
            for m in self._matcher.match(descriptors, chunk):
                d = int(round(m.distance))
                if d < dist[m.queryIdx]:
                    word[m.queryIdx] = start + m.trainIdx
                    dist[m.queryIdx] = d
        return word, dist

    def _append_words(self, descriptors: np.ndarray) -> np.ndarray:
        n = len(descriptors)
        need = self._n_words + n
        if need > len(self._words):
            cap = max(need, 2 * len(self._words))
            self._words = np.resize(self._words, (cap, DESCRIPTOR_BYTES))
            df = np.zeros(cap, np.int64)
            df[: len(self._df)] = self._df
            self._df = df
        ids = np.arange(self._n_words, need, dtype=np.int64)
        self._dictionary_version += 1
        self._words[self._n_words : need] = descriptors
        self._n_words = need
        if self._index is not None:
            self._index.add(np.ascontiguousarray(descriptors))
            self._index_words = np.concatenate([self._index_words, ids])
        return ids

    def forget_unused(self, least: int = 4096) -> bool:
        """Rebuild the search index over the words some indexed node holds, once those no node
        holds outnumber them (and `least`); True if it was rebuilt. Call it where no word ids
        handed out are still waiting to be indexed (after `add_words`): a word just founded and
        not yet in a bag would be dropped."""
        if self._index is None:
            return False
        held = self._df[self._index_words] > 0
        kept = int(held.sum())
        if len(held) - kept <= max(kept, least):
            return False
        keep = self._index_words[held]
        index = _faiss_index(self._index_kind)
        if len(keep):
            index.add(np.ascontiguousarray(self._words[keep]))
        self._index, self._index_words = index, keep
        self._dictionary_version += 1
        self.index_rebuilds += 1
        return True

    def quantise(self, descriptors: np.ndarray, grow: bool = False) -> np.ndarray:
        """Word id per descriptor (first `max_words_per_image` only); -1 where none is near enough.

        With `grow`, descriptors far from every word found new words; descriptors of the same
        image that are near each other share one new word, so a repeated pattern is not split
        into several words that would each look rare.
        """
        descriptors = _check_descriptors(descriptors)[: self.max_words_per_image]
        word, dist = self._nearest(descriptors)
        far = dist > self.max_distance
        word[far] = -1
        if grow and far.any():
            new = descriptors[far]
            d = hamming_matrix(new, new)
            label = np.full(len(new), -1, np.int64)
            leaders: list[int] = []
            for i in range(len(new)):  # greedy leader clustering; n <= max_words_per_image
                if label[i] >= 0:
                    continue
                members = (label < 0) & (d[i] <= self.max_distance)
                label[members] = len(leaders)
                leaders.append(i)
            ids = self._append_words(new[leaders])
            word[far] = ids[label]
        return word

    # --- inverted index ---------------------------------------------------------------------
    def add(self, node_id: int, descriptors: np.ndarray) -> np.ndarray:
        """Add a node's descriptors (strongest first) to the dictionary and the index.

        Returns the word id of each kept descriptor. Re-adding a node replaces its bag.
        """
        word = self.quantise(descriptors, grow=True)
        self.add_words(node_id, word)
        return word

    def add_words(self, node_id: int, word: np.ndarray) -> None:
        """Index a node by word ids already quantised (with `grow=True`), so a caller that
        queries and then adds the same image searches the dictionary once, not twice."""
        if node_id in self._bags:
            self.remove(node_id)
        word = np.asarray(word, np.int64)
        ids, counts = np.unique(word[word >= 0], return_counts=True)
        self._bags[node_id] = (ids, counts.astype(np.int64))
        self._df[ids] += 1
        self._matrix = None

    def remove(self, node_id: int) -> None:
        """Take a node out of the index (it left working memory); its words stay in the dictionary."""
        bag = self._bags.pop(node_id, None)
        if bag is None:
            return
        self._df[bag[0]] -= 1
        self._matrix = None

    def _tf_matrix(self) -> sp.csr_matrix:
        # Rebuilt only after add/remove; a query loop then costs sparse products only.
        if self._matrix is None or self._matrix.shape[1] != self._n_words:
            self._row_ids = np.fromiter(self._bags.keys(), np.int64, len(self._bags))
            bags = list(self._bags.values())
            lengths = np.array([len(w) for w, _ in bags], np.int64)
            cols = np.concatenate([w for w, _ in bags]) if bags else np.zeros(0, np.int64)
            counts = np.concatenate([c for _, c in bags]) if bags else np.zeros(0, np.int64)
            rows = np.repeat(np.arange(len(bags)), lengths)
            totals = np.array([c.sum() for _, c in bags], np.float64)
            tf = counts / np.maximum(np.repeat(totals, lengths), 1.0)
            self._matrix = sp.csr_matrix((tf, (rows, cols)), shape=(len(bags), self._n_words))
            self._columns = self._idf = self._norms = None
        return self._matrix

    def _scoring(self) -> tuple[sp.csc_matrix, np.ndarray, np.ndarray]:
        """The tf matrix by columns, each word's idf and each node's tf-idf norm, as of the nodes
        indexed now."""
        tf = self._tf_matrix()
        if self._norms is None:
            self._idf = self.idf()
            self._norms = np.sqrt(tf.multiply(tf) @ (self._idf**2))
            self._columns = tf.tocsc()
        return self._columns, self._idf, self._norms

    def idf(self) -> np.ndarray:
        """log(N / df) per word over the nodes in working memory (0 for words no node holds)."""
        n = max(len(self._bags), 1)
        df = self._df[: self._n_words]
        return np.where(df > 0, np.log(n / np.maximum(df, 1)), 0.0)

    def query(
        self, descriptors: np.ndarray, candidates: list[int] | np.ndarray | None = None, top_k: int = 5
    ) -> list[tuple[int, float]]:
        """Nodes most similar to `descriptors`, best first, as (node_id, score).

        The score is the cosine of tf-idf vectors, in [0, 1]: 1 for an identical bag, near 0 for
        a place that shares only common words. Cosine rather than a raw dot product so that
        nodes with many words do not win every query. The dictionary is not grown by a query.
        """
        if top_k <= 0 or not self._bags:
            return []
        return self.query_words(self.quantise(descriptors, grow=False), candidates, top_k)

    def query_words(
        self, word: np.ndarray, candidates: list[int] | np.ndarray | None = None, top_k: int = 5
    ) -> list[tuple[int, float]]:
        """`query` for word ids already quantised. Words that no indexed node holds (new words
        of this very image included) have no idf and do not count."""
        if top_k <= 0 or not self._bags:
            return []
        word = np.asarray(word, np.int64)
        word = word[word >= 0]
        if len(word) == 0:
            return []
        ids, counts = np.unique(word, return_counts=True)
        columns, idf, norms = self._scoring()
        q = counts / counts.sum() * idf[ids]
        q_norm = np.linalg.norm(q)
        if q_norm == 0.0:  # every matched word is in every node: nothing discriminates
            return []
        dots = columns[:, ids] @ (q * idf[ids])
        scores = np.where(norms > 0, dots / np.maximum(norms, 1e-300) / q_norm, 0.0)
        rows = np.arange(len(self._row_ids))
        if candidates is not None:
            rows = rows[np.isin(self._row_ids, np.asarray(list(candidates), np.int64))]
        rows = rows[scores[rows] > 0.0]
        if len(rows) == 0:
            return []
        k = min(top_k, len(rows))
        best = rows[np.argpartition(-scores[rows], k - 1)[:k]] if k < len(rows) else rows
        best = best[np.lexsort((self._row_ids[best], -scores[best]))]  # ties: lowest node id first
        return [(int(self._row_ids[r]), float(scores[r])) for r in best]


# --- geometric verification ---------------------------------------------------------------------
@dataclass
class Verification:
    accepted: bool
    inliers: int
    # Pose of the query camera in the candidate camera frame (4x4, maps query-camera coordinates
    # to candidate-camera coordinates); None unless accepted.
    transform: np.ndarray | None
    reason: str
    matches: int = 0


def match_descriptors(a: np.ndarray, b: np.ndarray, ratio: float = 0.8) -> np.ndarray:
    """(K, 2) index pairs (into a, into b) passing Lowe's ratio test, one per descriptor of a."""
    a, b = _check_descriptors(a), _check_descriptors(b)
    if len(a) == 0 or len(b) < 2:
        return np.zeros((0, 2), np.int64)
    # An exact search, so the same pairs as OpenCV's brute-force knnMatch: where the two nearest
    # tie, whichever comes first, the ratio test refuses the match. faiss's single-threaded flat
    # search takes half the time of OpenCV's on two threads, and needs no loop over DMatch objects.
    index = _faiss_index("flat")
    index.add(b)
    dist, nearest = index.search(a, 2)
    passed = np.flatnonzero(dist[:, 0] < ratio * dist[:, 1])
    if not len(passed):
        return np.zeros((0, 2), np.int64)
    pairs = np.column_stack([passed, nearest[passed, 0]]).astype(np.int64)
    # Keep one match per train descriptor: two query keypoints on one 3D point would bias PnP.
    _, first = np.unique(pairs[:, 1], return_index=True)
    return pairs[np.sort(first)]


def verify(
    query: Features,
    candidate: Features,
    intrinsics: Intrinsics,
    min_inliers: int = 20,
    ratio: float = 0.8,
    reprojection_error: float = 3.0,
    iterations: int = 200,
) -> Verification:
    """Check a loop-closure hypothesis with PnP RANSAC on the candidate's depth points.

    solvePnPRansac returns (R, t) with x_query = R X_candidate + t, i.e. the candidate frame
    expressed in the query camera; the returned `transform` is its inverse, the query camera's
    pose in the candidate camera frame, so that pose_query_world = pose_candidate_world @ transform.
    """
    if len(query) == 0:
        return Verification(False, 0, None, "query has no features")
    if len(candidate) == 0:
        return Verification(False, 0, None, "candidate has no features")
    valid = np.flatnonzero(candidate.valid)
    if len(valid) < min_inliers:
        return Verification(False, 0, None, f"candidate has {len(valid)} points with depth, need {min_inliers}")
    pairs = match_descriptors(query.descriptors, candidate.descriptors[valid], ratio)
    n_matches = len(pairs)
    if n_matches < max(min_inliers, 6):
        return Verification(False, 0, None, f"{n_matches} descriptor matches, need {min_inliers}", n_matches)
    object_points = candidate.points[valid[pairs[:, 1]]].astype(np.float64)
    image_points = query.keypoints[pairs[:, 0]].astype(np.float64)
    try:
        ok, rvec, tvec, inliers = cv2.solvePnPRansac(
            object_points,
            image_points,
            intrinsics.matrix,
            None,
            iterationsCount=iterations,
            reprojectionError=reprojection_error,
            confidence=0.99,
            flags=cv2.SOLVEPNP_SQPNP,
        )
    except cv2.error as err:
        return Verification(False, 0, None, f"PnP failed: {err.err}", n_matches)
    n_inliers = 0 if inliers is None else len(inliers)
    if not ok or n_inliers == 0:
        return Verification(False, 0, None, "PnP RANSAC found no pose", n_matches)
    inl = inliers.ravel()
    if n_inliers >= 4:
        # RANSAC's pose comes from a minimal set; polishing on all inliers cuts its noise.
        rvec, tvec = cv2.solvePnPRefineLM(object_points[inl], image_points[inl], intrinsics.matrix, None, rvec, tvec)
    rot, _ = cv2.Rodrigues(rvec)
    candidate_in_query = np.eye(4)
    candidate_in_query[:3, :3] = rot
    candidate_in_query[:3, 3] = np.asarray(tvec).ravel()
    if not np.all(np.isfinite(candidate_in_query)):
        return Verification(False, n_inliers, None, "PnP returned a non-finite pose", n_matches)
    if n_inliers < min_inliers:
        # No transform: a pose from too few inliers is as likely wrong as right.
        return Verification(False, n_inliers, None, f"{n_inliers} inliers, need {min_inliers}", n_matches)
    transform = invert(candidate_in_query)
    return Verification(True, n_inliers, transform, f"{n_inliers} inliers of {n_matches} matches", n_matches)


# A 3D-3D match supports a transform if it lands within this many pixels' footprint at its
# distance (or `max_residual`, whichever is more): a fixed 5 cm held no loop at 160 x 120.
SUPPORT_PIXELS = 3.0


@dataclass
class Refinement:
    # Query camera in candidate camera: polished if every round had its matches, else the input
    # unchanged (a half-finished polish is checked by nothing).
    transform: np.ndarray
    polished: bool
    # Matches with depth on both sides that land within max(max_residual, SUPPORT_PIXELS pixels'
    # footprint) of `transform`: how far both images' depth hold it (0 without `focal`).
    support: int


def refine_3d(
    query: Features,
    candidate: Features,
    transform: np.ndarray,
    ratio: float = 0.8,
    max_residual: float = 0.05,
    min_inliers: int = 10,
) -> np.ndarray:
    """Polish a verified transform (query camera in candidate camera) on 3D-3D matches.

    PnP uses the candidate's depth only; with depth on both sides, aligning the matched 3D
    points (Kabsch on the inliers, a few rounds with a shrinking gate) removes most of PnP's
    error at low image resolution (RTAB-Map's Vis/EstimationType 0). Returns the input when
    too few matches have depth on both sides for any round.
    """
    return refine_3d_checked(query, candidate, transform, None, ratio, max_residual, min_inliers).transform


def refine_3d_checked(
    query: Features,
    candidate: Features,
    transform: np.ndarray,
    focal: float | None,
    ratio: float = 0.8,
    max_residual: float = 0.05,
    min_inliers: int = 10,
    sigma_w: float | None = None,
) -> Refinement:
    """`refine_3d`, with how many 3D-3D matches support the result (`focal`: pixels). Depth of
    inverse-depth noise `sigma_w` (1/m) widens each match's gates by its two points' range noise."""
    pairs = match_descriptors(query.descriptors, candidate.descriptors, ratio)
    given = np.asarray(transform, dtype=np.float64)
    q, c = query.points[pairs[:, 0]].astype(np.float64), candidate.points[pairs[:, 1]].astype(np.float64)
    both = np.isfinite(q).all(axis=1) & np.isfinite(c).all(axis=1)
    q, c = q[both], c[both]

    def residual(t: np.ndarray) -> np.ndarray:
        return np.linalg.norm(c - (q @ t[:3, :3].T + t[:3, 3]), axis=1)

    # 3 stds of the difference of two points' range noise sigma_w z^2 (0 for exact depth).
    noise = 0.0 if sigma_w is None else 3.0 * sigma_w * np.hypot(q[:, 2] ** 2, c[:, 2] ** 2)

    current, polished = given, len(pairs) >= min_inliers
    for gate in (3.0 * max_residual, max_residual, max_residual) if polished else ():
        inliers = residual(current) < np.maximum(gate, noise)
        if inliers.sum() < min_inliers:
            current, polished = given, False
            break
        current = rigid_transform(q[inliers], c[inliers])
    support = 0
    if focal is not None and len(q):
        gate = np.maximum(np.maximum(max_residual, SUPPORT_PIXELS * np.linalg.norm(c, axis=1) / focal), noise)
        support = int((residual(current) < gate).sum())
    return Refinement(current, polished, support)


def depth_held_transform(
    query: Features,
    candidate: Features,
    transform: np.ndarray,
    focal: float,
    polish: bool,
    min_support: int,
    sigma_w: float | None = None,
) -> np.ndarray | None:
    """The PnP-verified `transform` a loop keeps: polished on the 3D-3D matches if `polish`, or
    None when fewer than `min_support` of them hold it (0: not checked); `sigma_w`: the depth's noise."""
    if not (polish or min_support):
        return transform
    refined = refine_3d_checked(query, candidate, transform, focal, sigma_w=sigma_w)
    if refined.support < min_support:
        return None
    # Noisy depth on both sides would move PnP's transform, which holds the query's bearings exact.
    return refined.transform if polish and sigma_w is None else transform


def noisy_link_sigmas(points: np.ndarray, sigma_w: float | None, linear: float, angular: float) -> tuple[float, float]:
    """A loop link's stds (m, rad) widened by its depth's range noise at the median depth of the
    3D `points` that place it (camera frame): sigma_w z^2, and that over z for the heading. The
    given stds for exact depth (`sigma_w` None)."""
    if sigma_w is None:
        return linear, angular
    z = np.asarray(points, dtype=np.float64)[:, 2]
    z = z[np.isfinite(z) & (z > 0)]
    if not len(z):
        return linear, angular
    median = float(np.median(z))
    noise = sigma_w * median * median
    return float(np.hypot(linear, noise)), float(np.hypot(angular, noise / median))


# A verified loop transform must be planar: the camera neither rises nor tilts on this robot.
MAX_LOOP_Z = 0.3  # m
MAX_LOOP_TILT = 0.2  # rad


def planar_link(camera_in_base: np.ndarray, camera_transform: np.ndarray) -> np.ndarray | None:
    """The query robot's pose in the candidate robot's frame as (x, y, yaw), from the verified
    transform of the query camera in the candidate camera; None if that motion is not planar (a
    sign of a wrong match)."""
    base = camera_in_base @ camera_transform @ invert(camera_in_base)
    tilt = np.arccos(np.clip(base[2, 2], -1.0, 1.0))
    if abs(base[2, 3]) > MAX_LOOP_Z or tilt > MAX_LOOP_TILT:
        return None
    return xyyaw_from_pose(base)
