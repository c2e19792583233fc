"""A DBoW2 vocabulary tree: hierarchical k-means over binary descriptors, with IDF word weights.

Nodes are numbered as DBoW2's `TemplatedVocabulary::create` numbers them: the root is 0, a node's
children get consecutive ids when its k-means runs, and the tree grows depth first (all children
of a node, then the subtree under the first child, and so on). DBoW2's text loader gives each
line the next id and needs only that a parent comes before its children, which this order keeps.
The words are the leaves in id order, the order in which the loader numbers them.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from longslam.vocabulary.kmeans import CHUNK, check_descriptors, kmeans, xor_popcount

# DBoW2's enums (BowVector.h): WeightingType {TF_IDF, TF, IDF, BINARY}, ScoringType {L1_NORM,
# L2_NORM, CHI_SQUARE, KL, BHATTACHARYYA, DOT_PRODUCT}. ORB-SLAM3's ORBvoc.txt uses TF_IDF and L1_NORM.
TF_IDF = 0
L1_NORM = 0


@dataclass(frozen=True, eq=False)
class Vocabulary:
    """A vocabulary tree. Arrays are indexed by node id; node 0 is the root (parent -1, a zero
    descriptor and weight, never written to a file)."""

    k: int
    levels: int
    parents: np.ndarray  # (nodes,) int64
    descriptors: np.ndarray  # (nodes, bytes) uint8
    weights: np.ndarray  # (nodes,) float64: a word's IDF, 0 for inner nodes
    scoring: int = L1_NORM
    weighting: int = TF_IDF

    def __post_init__(self) -> None:
        # Contiguous arrays of fixed types: `transform` views the descriptors as uint64 words.
        object.__setattr__(self, "parents", np.ascontiguousarray(self.parents, dtype=np.int64))
        object.__setattr__(self, "descriptors", check_descriptors(self.descriptors, "node descriptors"))
        object.__setattr__(self, "weights", np.ascontiguousarray(self.weights, dtype=np.float64))
        n = len(self.parents)
        if n < 2:
            raise ValueError("a vocabulary needs a root and at least one word")
        if self.descriptors.shape[0] != n or self.weights.shape != (n,):
            raise ValueError(f"parents, descriptors and weights must have one row per node ({n})")
        if self.parents[0] != -1 or np.any(self.parents[1:] < 0) or np.any(self.parents[1:] >= np.arange(1, n)):
            raise ValueError("every node's parent must come before it, and only the root has none")

    @property
    def nodes(self) -> int:
        """Nodes with the root."""
        return len(self.parents)

    @cached_property
    def is_leaf(self) -> np.ndarray:
        """(nodes,) bool: nodes without children; the root is never a leaf."""
        leaf = np.ones(self.nodes, dtype=bool)
        leaf[self.parents[1:]] = False
        leaf[0] = False
        return leaf

    @cached_property
    def words(self) -> np.ndarray:
        """Node id of each word, in word-id order."""
        return np.flatnonzero(self.is_leaf)

    @cached_property
    def children(self) -> np.ndarray:
        """(nodes, max children) int64 child ids in id order, -1 past a node's last child."""
        counts = np.bincount(self.parents[1:], minlength=self.nodes)
        table = np.full((self.nodes, max(1, int(counts.max()))), -1, dtype=np.int64)
        ids = np.arange(1, self.nodes)
        order = np.argsort(self.parents[1:], kind="stable")  # children of a parent stay in id order
        parent = self.parents[1:][order]
        starts = np.concatenate([[0], np.cumsum(counts)])[parent]
        table[parent, np.arange(len(order)) - starts] = ids[order]
        return table

    def transform(self, descriptors: np.ndarray) -> np.ndarray:
        """The word id of each descriptor: from the root down, the nearest child at each level
        (the first on a tie), as DBoW2's `transform`."""
        descriptors = check_descriptors(descriptors)
        if descriptors.shape[1] != self.descriptors.shape[1]:
            raise ValueError(
                f"descriptors of {descriptors.shape[1]} bytes for a vocabulary of "
                f"{self.descriptors.shape[1]}-byte words"
            )
        word_of_node = np.cumsum(self.is_leaf) - 1
        nodes64 = self.descriptors.view(np.uint64)
        children, is_leaf = self.children, self.is_leaf
        out = np.empty(len(descriptors), dtype=np.int64)
        for start in range(0, len(descriptors), CHUNK):
            block = descriptors[start : start + CHUNK].view(np.uint64)
            node = np.zeros(len(block), dtype=np.int64)
            active = np.arange(len(block))
            while active.size:
                kids = children[node[active]]
                distance = xor_popcount(block[active][:, None, :], nodes64[kids]).astype(np.int32)
                distance[kids < 0] = np.iinfo(np.int32).max
                node[active] = kids[np.arange(len(active)), np.argmin(distance, axis=1)]
                active = active[~is_leaf[node[active]]]
            out[start : start + len(block)] = word_of_node[node]
        return out


def idf_weights(vocabulary: Vocabulary, images: Sequence[np.ndarray]) -> np.ndarray:
    """Each word's ln(N / N_i), N images and N_i of them holding the word (DBoW2's
    `setNodeWeights` for TF_IDF); 0 for a word no image holds, as DBoW2 leaves it."""
    words = len(vocabulary.words)
    seen = np.zeros(words, dtype=np.int64)
    if len(images):
        sizes = np.array([len(image) for image in images])
        labels = vocabulary.transform(np.concatenate(images))
        image_of = np.repeat(np.arange(len(images)), sizes)
        pairs = np.unique(image_of * words + labels)  # each (image, word) once
        seen += np.bincount(pairs % words, minlength=words)
    weights = np.zeros(words)
    held = seen > 0
    weights[held] = np.log(len(images) / seen[held])
    return weights


def build_tree(
    images: Sequence[np.ndarray],
    k: int,
    levels: int,
    rng: np.random.Generator,
    progress: Callable[[int], None] | None = None,
    max_iterations: int = 100,
) -> Vocabulary:
    """DBoW2's `create(training_features, k, L)` with TF_IDF weighting and L1 scoring.

    `images` holds one (n_i, bytes) uint8 array of descriptors per training image. `progress`,
    if given, is called with the number of descriptors each finished branch settled (they add up
    to the total).
    """
    if k < 2:
        raise ValueError(f"k (branching factor) must be at least 2, got {k}")
    if levels < 1:
        raise ValueError(f"L (depth levels) must be at least 1, got {levels}")
    images = [check_descriptors(image, f"image {i}'s descriptors") for i, image in enumerate(images)]
    images = [image for image in images if len(image)]
    if not images:
        raise ValueError("no descriptors to build a vocabulary from")
    if len({image.shape[1] for image in images}) > 1:
        raise ValueError("the images' descriptors differ in length")
    everything = np.concatenate(images)

    parents: list[int] = [-1]
    centres: list[np.ndarray] = [np.zeros(everything.shape[1], dtype=np.uint8)]

    def step(parent: int, members: np.ndarray, level: int) -> None:
        found, labels = kmeans(everything[members], k, rng, max_iterations)
        first = len(parents)
        parents.extend([parent] * len(found))
        centres.extend(found)
        order = np.argsort(labels, kind="stable")
        groups = np.split(members[order], np.cumsum(np.bincount(labels, minlength=len(found)))[:-1])
        for i, group in enumerate(groups):
            if level < levels and len(group) > 1:
                step(first + i, group, level + 1)
            elif progress is not None:
                progress(len(group))

    step(0, np.arange(len(everything)), 1)
    tree = Vocabulary(
        k, levels, np.array(parents, dtype=np.int64), np.array(centres, dtype=np.uint8), np.zeros(len(parents))
    )
    weights = np.zeros(tree.nodes)
    weights[tree.words] = idf_weights(tree, images)
    return Vocabulary(k, levels, tree.parents, tree.descriptors, weights)
