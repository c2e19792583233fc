"""DBoW2's text vocabulary format, as ORB-SLAM3's `TemplatedVocabulary::loadFromTextFile` reads it.

    k L scoringType weightingType
    parentId isLeaf d_0 d_1 ... d_31 weight      <- one line per node but the root, node 1 first

- The header's four integers are read with `>>`; the loader refuses k outside 0..20, L outside
  1..10, scoring outside 0..5 and weighting outside 0..3.
- A node's id is its line number (1 for the first node line): the loader gives each line the
  next id and appends it to its parent's children, so a parent must come before its children.
- isLeaf > 0 makes the node a word; words are numbered in line order. The loader trusts the flag,
  but its `transform` descends while a node has children, so the flag must match the tree.
- The descriptor is FORB's: 32 bytes as decimal integers 0..255; the weight a double (the IDF of a
  word, 0 for an inner node).
- The file must not end with a newline: the loader reads lines until EOF, so a final newline
  gives one more, empty, line, which becomes a broken extra child of the root (parent 0, an
  uninitialised descriptor). ORB-SLAM3's own `saveToTextFile` writes that newline; we do not.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from longslam.errors import InputError
from longslam.io.atomic import atomic_path, naming_the_file
from longslam.textfile import read_text
from longslam.vocabulary.tree import Vocabulary

DESCRIPTOR_BYTES = 32  # FORB::L
# The loader's own bounds on the header (loadFromTextFile).
HEADER_LIMITS = {"k": (0, 20), "L": (1, 10), "scoringType": (0, 5), "weightingType": (0, 3)}

_BYTE_TEXT = [str(i) for i in range(256)]


def _weight_text(weight: float) -> str:
    # repr is the shortest text that reads back to the same double.
    return "0" if weight == 0 else repr(float(weight))


def format_text(vocabulary: Vocabulary) -> str:
    """The vocabulary as DBoW2 text, without a final newline."""
    if vocabulary.descriptors.shape[1] != DESCRIPTOR_BYTES:
        raise ValueError(f"DBoW2's ORB text format holds {DESCRIPTOR_BYTES}-byte descriptors, "
                         f"not {vocabulary.descriptors.shape[1]}")
    header = (vocabulary.k, vocabulary.levels, vocabulary.scoring, vocabulary.weighting)
    for (name, (low, high)), value in zip(HEADER_LIMITS.items(), header):
        if not low <= value <= high:
            raise ValueError(f"{name} = {value} is outside {low}..{high}, which ORB-SLAM3's loader refuses")
    lines = [" ".join(str(v) for v in header)]
    leaf = vocabulary.is_leaf
    for node, (parent, row, weight) in enumerate(
        zip(vocabulary.parents.tolist(), vocabulary.descriptors.tolist(), vocabulary.weights.tolist())
    ):
        if node == 0:
            continue
        lines.append(f"{parent} {int(leaf[node])} {' '.join(_BYTE_TEXT[b] for b in row)} {_weight_text(weight)}")
    return "\n".join(lines)


def write_vocabulary(vocabulary: Vocabulary, path: str | Path, overwrite: bool = True) -> Path:
    """Write the vocabulary to `path` atomically (a temporary sibling, renamed when complete);
    with `overwrite=False` an existing file is never replaced (InputError)."""
    path = Path(path)
    text = format_text(vocabulary)
    with atomic_path(path, overwrite=overwrite) as tmp, naming_the_file(path):
        with open(tmp, "w", encoding="ascii", newline="") as f:
            f.write(text)
    return path


def _int(field: str, where: str, name: str) -> int:
    try:
        return int(field)
    except ValueError:
        raise InputError(f"{where}: {name} {field!r} is not an integer") from None


def read_vocabulary(path: str | Path, final_newline: bool = False) -> Vocabulary:
    """Read a DBoW2 text vocabulary of ORB descriptors, checking what ORB-SLAM3's loader needs.

    Raises InputError naming the file and line for anything the loader would refuse or misread.
    A final newline is refused unless `final_newline`: ORB-SLAM3's own ORBvoc.txt, written by
    `saveToTextFile`, has one, and ORB-SLAM3 copes with the broken node it makes of it (a leaf
    by its lack of children but no word, so features that reach it are dropped).
    """
    path = Path(path)
    text = read_text(path, "vocabulary", encoding="ascii")
    if text.endswith("\n") and final_newline:
        text = text[:-1]
    if text.endswith("\n"):
        raise InputError(f"vocabulary {path} ends with a newline, which ORB-SLAM3's text loader reads "
                         "as one more, broken, node; remove the final newline")
    lines = text.split("\n")
    fields = lines[0].split()
    if len(fields) != 4:
        raise InputError(f"{path}:1: expected 'k L scoringType weightingType', got {lines[0]!r}")
    header = [_int(f, f"{path}:1", name) for f, name in zip(fields, HEADER_LIMITS)]
    for (name, (low, high)), value in zip(HEADER_LIMITS.items(), header):
        if not low <= value <= high:
            raise InputError(f"{path}:1: {name} = {value} is outside {low}..{high}, which ORB-SLAM3's loader refuses")
    k, levels, scoring, weighting = header
    n = len(lines)  # nodes with the root
    if n < 2:
        raise InputError(f"vocabulary {path} has a header but no nodes")
    parents = np.full(n, -1, dtype=np.int64)
    leaf_flags = np.zeros(n, dtype=bool)
    descriptors = np.zeros((n, DESCRIPTOR_BYTES), dtype=np.uint8)
    weights = np.zeros(n)
    width = 2 + DESCRIPTOR_BYTES + 1
    for node in range(1, n):
        where = f"{path}:{node + 1}"
        parts = lines[node].split()
        if len(parts) != width:
            raise InputError(f"{where}: expected {width} fields (parent, isLeaf, {DESCRIPTOR_BYTES} bytes, "
                             f"weight), got {len(parts)}")
        parent = _int(parts[0], where, "parent id")
        if not 0 <= parent < node:
            raise InputError(f"{where}: parent id {parent} must be a node before this one (0..{node - 1})")
        if leaf_flags[parent]:
            raise InputError(f"{where}: parent {parent} is marked as a leaf (isLeaf 1) but has children")
        parents[node] = parent
        leaf_flags[node] = _int(parts[1], where, "isLeaf") > 0
        try:
            row = np.array(parts[2:2 + DESCRIPTOR_BYTES], dtype=np.int64)
        except ValueError:
            raise InputError(f"{where}: descriptor bytes must be integers, got {parts[2:2 + DESCRIPTOR_BYTES]}") from None
        if row.min() < 0 or row.max() > 255:
            raise InputError(f"{where}: descriptor bytes must be 0..255")
        descriptors[node] = row
        try:
            weights[node] = float(parts[-1])
        except ValueError:
            raise InputError(f"{where}: weight {parts[-1]!r} is not a number") from None
        if not math.isfinite(weights[node]):
            raise InputError(f"{where}: weight {parts[-1]!r} is not finite")
    vocabulary = Vocabulary(k, levels, parents, descriptors, weights, scoring, weighting)
    wrong = np.flatnonzero(vocabulary.is_leaf[1:] != leaf_flags[1:])
    if wrong.size:
        node = int(wrong[0]) + 1
        raise InputError(f"{path}:{node + 1}: isLeaf is {int(leaf_flags[node])} but the node has "
                         f"{'no ' if vocabulary.is_leaf[node] else ''}children")
    return vocabulary
