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

import io
import math
from pathlib import Path

import numpy as np

from longslam.core.errors import InputError
from longslam.core.file_kinds import special_file_kind
from longslam.core.textfile import read_text
from longslam.io.atomic import atomic_path, naming_the_file
from longslam.vocabulary.tree import Vocabulary

DESCRIPTOR_BYTES = 32  # FORB::L
# The loader's own bounds on the header (loadFromTextFile).
HEADER_LIMITS = {"k": (0, 20), "L": (1, 10), "scoringType": (0, 5), "weightingType": (0, 3)}
# Before it reads a node, the loader reserves room for a full tree: `(int)((k^(L+1) - 1) / (k - 1))`
# nodes of about 152 bytes (FORB's cv::Mat descriptor, a children vector, ids, a weight) and
# k^(L+1) word pointers. Past 2^31 - 1 nodes the int overflows and the reserve throws
# "vector::reserve" (k = 20, L = 10); below, a reservation larger than the machine can grant is
# std::bad_alloc (k = 20, L = 7 on 23 GB; k = 10, L = 8 reserved 25 GB there and loaded). longslam
# keeps to reservations of 4 GB, ORB-SLAM3's own ORBvoc.txt (k = 10, L = 6) being 0.25 GB.
LOADER_NODE_BYTES = 152
LOADER_MAX_NODES = 2**31 - 1
LOADER_MAX_RESERVED_BYTES = 4 * 10**9
MAX_LINE_BYTES = 1024  # a node line is about 150 characters; ORBvoc.txt's longest is 145
CHUNK_BYTES = 1 << 23  # node lines checked a block at a time: about 55,000 of them

_BYTE_TEXT = [str(i) for i in range(256)]


def loader_reservation(k: int, levels: int) -> tuple[int, int]:
    """(nodes, bytes) that DBoW2's text loader reserves for a header with `k` and `levels`."""
    if k < 2:
        return 1, LOADER_NODE_BYTES
    words = k ** (levels + 1)
    nodes = (words - 1) // (k - 1)
    return nodes, nodes * LOADER_NODE_BYTES + words * 8


def loader_size_problem(k: int, levels: int) -> str | None:
    """Why ORB-SLAM3's loader could not load a vocabulary with this k and L, or None."""
    nodes, reserved = loader_reservation(k, levels)
    if nodes > LOADER_MAX_NODES:
        return (
            f"k = {k}, L = {levels} makes ORB-SLAM3's loader reserve {nodes:.3g} nodes, more than its int "
            f"holds ({LOADER_MAX_NODES}): it stops with 'vector::reserve'"
        )
    if reserved > LOADER_MAX_RESERVED_BYTES:
        return (
            f"k = {k}, L = {levels} makes ORB-SLAM3's loader reserve {reserved / 1e9:.3g} GB before it reads a "
            f"node (a full tree of k^(L+1) words); longslam keeps to {LOADER_MAX_RESERVED_BYTES / 1e9:g} GB "
            "(ORBvoc.txt's k = 10, L = 6: 0.25 GB)"
        )
    return None


def _weight_text(weight: float) -> str:
    # repr is the shortest text that reads back to the same double.
    return "0" if weight == 0 else repr(float(weight))


def format_text(vocabulary: Vocabulary) -> str:
    """The vocabulary as DBoW2 text, without a final newline."""
    if vocabulary.descriptors.shape[1] != DESCRIPTOR_BYTES:
        raise ValueError(
            f"DBoW2's ORB text format holds {DESCRIPTOR_BYTES}-byte descriptors, "
            f"not {vocabulary.descriptors.shape[1]}"
        )
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


def _prefix(raw: bytes) -> str:
    """A short, printable picture of a line that is not what was expected. A line that is not
    text (a binary file given as a vocabulary) is called so, with only its first 4 bytes, which
    name most formats (ELF, PNG, a zip's PK), not echoed as 40 escaped bytes."""
    binary = f"{raw[:4]!r}... (binary data, not text)"
    try:
        text = raw[:200].decode("utf-8")
    except UnicodeDecodeError as err:
        if err.start < 200 - 4:  # not a character cut at the end of the slice
            return binary
        text = raw[: err.start].decode("utf-8")
    if any(not c.isprintable() and c not in "\t\r" for c in text):
        return binary
    return repr(text[:40]) + (" ..." if len(raw) > 40 else "")


def _node_chunks(handle, where: str):
    """The node lines of an open vocabulary (after its header) in blocks of whole lines, as bytes;
    a line longer than MAX_LINE_BYTES is refused before more of it is read."""
    carry = b""
    lines_before = 1  # the header
    while True:
        block = handle.read(CHUNK_BYTES)
        if not block:
            if carry:
                yield lines_before, carry
            return
        block = carry + block
        cut = block.rfind(b"\n") + 1
        carry = block[cut:]
        complete = block.count(b"\n", 0, cut)
        if len(carry) > MAX_LINE_BYTES:
            raise InputError(
                f"{where}:{lines_before + complete + 1}: a line longer than {MAX_LINE_BYTES} bytes "
                f"({_prefix(carry)}); a node line is about 150"
            )
        if cut:
            yield lines_before, block[:cut]
            lines_before += complete


def _first_bad_line(lines: list[bytes], width: int) -> tuple[int, str]:
    """The index of the first line that is not `width` numbers, and what is wrong with it."""
    for i, line in enumerate(lines):
        parts = line.split()
        if not parts:
            return i, "an empty line, which ORB-SLAM3 would read as a broken node"
        if len(parts) != width:
            return (
                i,
                f"expected {width} fields (parent, isLeaf, {DESCRIPTOR_BYTES} bytes, weight), got {len(parts)}: "
                f"{_prefix(line)}",
            )
        try:
            for part in parts:
                float(part)
        except ValueError:
            return i, f"expected {width} numbers: {_prefix(line)}"
    return 0, f"cannot be read as {width} numbers a line: {_prefix(lines[0])}"


def check_vocabulary_file(path: str | Path, what: str = "vocabulary", final_newline: bool = True) -> int:
    """Check, a block of lines at a time (a 1 GB file is never held), that ORB-SLAM3's text loader
    can load the file and build a sound tree from it; return the number of nodes, the root included.

    Its loader checks the header's ranges only: parent ids it has not seen yet crash it, a
    garbage line becomes a node of uninitialised fields, and a header whose full tree it cannot
    reserve room for stops it. Here: the header (its ranges and its reservation, see
    `loader_size_problem`), then every node line: 35 numbers, a parent before it that is not a
    word, isLeaf 0 or 1 and matching whether the node has children, 32 bytes 0..255, a finite
    weight; at most k children a node, L levels and the nodes a tree of k and L holds.
    `final_newline` accepts the final newline ORB-SLAM3's own saveToTextFile leaves (ORBvoc.txt
    has it). InputError names `what`, the file and the line, showing at most a short prefix of it.
    """
    path = Path(path)
    kind = special_file_kind(path)
    if kind is not None:  # opening a FIFO would wait for a writer
        raise InputError(f"{what}: {path} is {kind}; expected a vocabulary file")
    try:
        handle = open(path, "rb")
    except OSError as err:
        raise InputError(f"{what}: cannot read {path} ({err.strerror})") from None
    expected = "a DBoW2 text vocabulary (first line 'k L scoring weighting', e.g. '10 6 0 0' as ORBvoc.txt)"
    width = 2 + DESCRIPTOR_BYTES + 1
    with handle:
        raw = handle.readline(MAX_LINE_BYTES + 1)
        header = raw.split()
        if (
            len(raw) > MAX_LINE_BYTES
            or len(header) != 4
            or not all(h.lstrip(b"-").isdigit() and len(h) < 10 for h in header)
        ):
            raise InputError(f"{what}: {path} is not {expected}; its first line is {_prefix(raw.rstrip())}")
        values = [int(h) for h in header]
        for (name, (low, high)), value in zip(HEADER_LIMITS.items(), values):
            low = max(low, 2) if name == "k" else low  # the loader takes k = 0 and 1; a tree needs 2
            if not low <= value <= high:
                raise InputError(f"{what}: {path}:1: {name} = {value} is out of range ({low}..{high}) for {expected}")
        k, levels = values[0], values[1]
        problem = loader_size_problem(k, levels)
        if problem is not None:
            raise InputError(f"{what}: {path}:1: {problem}")
        most = loader_reservation(k, levels)[0]  # nodes with the root
        parents = [np.full(1, -1, np.int32)]  # per node id, the root first
        leaf = np.zeros(most, np.uint8)  # at most 26 MB within LOADER_MAX_RESERVED_BYTES
        nodes, ends_with_newline = 1, False
        for before, block in _node_chunks(handle, f"{what}: {path}"):
            ends_with_newline = block.endswith(b"\n")
            lines = block.split(b"\n")
            if ends_with_newline:
                lines.pop()

            def refuse(i: int, why: str, before: int = before) -> None:
                raise InputError(f"{what}: {path}:{before + i + 1}: {why}")

            if nodes + len(lines) > most:
                refuse(
                    most - nodes, f"more nodes than a tree of k = {k}, L = {levels} holds ({most - 1} below the root)"
                )
            longest = max(range(len(lines)), key=lambda i: len(lines[i]))
            if len(lines[longest]) > MAX_LINE_BYTES:
                refuse(
                    longest,
                    f"a line longer than {MAX_LINE_BYTES} bytes ({_prefix(lines[longest])}); "
                    "a node line is about 150",
                )
            if b"\0" in block:
                i = next(i for i, line in enumerate(lines) if b"\0" in line)
                refuse(i, f"a NUL byte: {_prefix(lines[i])}")
            try:
                table = np.loadtxt(io.BytesIO(block), dtype=np.float64, ndmin=2, comments=None)
            except ValueError:
                refuse(*_first_bad_line(lines, width))
            if table.shape != (len(lines), width):  # loadtxt skips empty lines
                refuse(*_first_bad_line(lines, width))
            ids = np.arange(nodes, nodes + len(lines))
            whole = table[:, : 2 + DESCRIPTOR_BYTES]
            bad = np.flatnonzero(np.any(whole != np.floor(whole), axis=1))
            if bad.size:
                refuse(
                    int(bad[0]),
                    f"parent id, isLeaf and the {DESCRIPTOR_BYTES} bytes must be whole numbers: "
                    f"{_prefix(lines[int(bad[0])])}",
                )
            parent, flags = table[:, 0], table[:, 1]
            bad = np.flatnonzero((parent < 0) | (parent >= ids))
            if bad.size:
                i = int(bad[0])
                refuse(i, f"parent id {parent[i]:.0f} must be a node before this one (0..{ids[i] - 1})")
            bad = np.flatnonzero((flags != 0) & (flags != 1))
            if bad.size:
                refuse(int(bad[0]), f"isLeaf must be 0 or 1, got {flags[int(bad[0])]:.0f}")
            bad = np.flatnonzero(np.any((whole[:, 2:] < 0) | (whole[:, 2:] > 255), axis=1))
            if bad.size:
                refuse(int(bad[0]), f"descriptor bytes must be 0..255: {_prefix(lines[int(bad[0])])}")
            bad = np.flatnonzero(~np.isfinite(table[:, -1]))
            if bad.size:
                refuse(int(bad[0]), f"weight {table[int(bad[0]), -1]} is not finite")
            parents.append(parent.astype(np.int32))
            leaf[ids] = flags
            bad = np.flatnonzero(leaf[parents[-1]] == 1)  # a parent in this block included
            if bad.size:
                i = int(bad[0])
                refuse(i, f"parent {parent[i]:.0f} is marked as a leaf (isLeaf 1) but has children")
            nodes += len(lines)
    if nodes == 1:
        raise InputError(f"{what}: {path} has a header but no nodes")
    if ends_with_newline and not final_newline:
        raise InputError(
            f"{what}: {path} ends with a newline, which ORB-SLAM3's text loader reads as one more, "
            "broken, node; remove the final newline"
        )
    parent = np.concatenate(parents)
    leaf = leaf[:nodes]
    children = np.bincount(parent[1:], minlength=nodes)
    wide = np.flatnonzero(children > k)
    if wide.size:
        node = int(wide[0])
        raise InputError(
            f"{what}: {path}:{node + 1}: node {node} has {children[node]} children, more than k = {k} " "of the header"
        )
    depth = np.zeros(nodes, np.int64)
    for _ in range(levels + 1):  # min(true depth, iterations): a node deeper than L ends at L + 1
        depth[1:] = depth[parent[1:]] + 1
    deep = np.flatnonzero(depth > levels)
    if deep.size:
        raise InputError(f"{what}: {path}:{int(deep[0]) + 1}: the node is deeper than L = {levels} of the header")
    _check_leaf_flags(f"{what}: {path}", leaf, children > 0)
    return nodes


def _check_leaf_flags(where: str, leaf: np.ndarray, has_children: np.ndarray) -> None:
    """InputError at the first node (the root aside) whose isLeaf flag says it has children when it
    has none, or none when it has some."""
    wrong = np.flatnonzero(leaf[1:] == has_children[1:])
    if wrong.size:
        node = int(wrong[0]) + 1
        raise InputError(
            f"{where}:{node + 1}: isLeaf is {int(leaf[node])} but the node has "
            f"{'' if has_children[node] else 'no '}children"
        )


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
        raise InputError(
            f"vocabulary {path} ends with a newline, which ORB-SLAM3's text loader reads "
            "as one more, broken, node; remove the final newline"
        )
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
            raise InputError(
                f"{where}: expected {width} fields (parent, isLeaf, {DESCRIPTOR_BYTES} bytes, "
                f"weight), got {len(parts)}"
            )
        parent = _int(parts[0], where, "parent id")
        if not 0 <= parent < node:
            raise InputError(f"{where}: parent id {parent} must be a node before this one (0..{node - 1})")
        if leaf_flags[parent]:
            raise InputError(f"{where}: parent {parent} is marked as a leaf (isLeaf 1) but has children")
        parents[node] = parent
        leaf_flags[node] = _int(parts[1], where, "isLeaf") > 0
        try:
            row = np.array(parts[2 : 2 + DESCRIPTOR_BYTES], dtype=np.int64)
        except ValueError:
            raise InputError(
                f"{where}: descriptor bytes must be integers, got {parts[2:2 + DESCRIPTOR_BYTES]}"
            ) from None
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
    _check_leaf_flags(str(path), leaf_flags, ~np.asarray(vocabulary.is_leaf, dtype=bool))
    return vocabulary
