"""A vocabulary file is checked whole before ORB-SLAM3 gets it, and `vocabulary build` refuses a
tree ORB-SLAM3's loader cannot load: its loader checks the header's ranges only, and a parent id
it has not read, a garbage line or a tree it cannot reserve room for crashed it."""

from __future__ import annotations

import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from helpers.cli_checks import one_line_error
from longslam.cli.main import main
from longslam.core.errors import InputError
from longslam.vocabulary import build_tree, format_text
from longslam.vocabulary.dbow2 import check_vocabulary_file, loader_size_problem


def _images(seed: int = 0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 256, (60, 32), dtype=np.uint8) for _ in range(3)]


@pytest.fixture(scope="module")
def good() -> str:
    """A vocabulary as longslam writes it: k = 3, L = 2."""
    return format_text(build_tree(_images(), 3, 2, np.random.default_rng(0)))


def _line(parent: int, leaf: int, byte: object = 0, weight: object = 0.5) -> str:
    return f"{parent} {leaf} {' '.join([str(byte)] * 32)} {weight}"


def test_what_longslam_writes_passes_and_a_final_newline_only_if_allowed(tmp_path, good):
    path = tmp_path / "voc.txt"
    path.write_text(good)
    assert check_vocabulary_file(path) == len(good.split("\n"))  # the header's line stands for the root
    path.write_text(good + "\n")  # as ORB-SLAM3's saveToTextFile leaves ORBvoc.txt
    assert check_vocabulary_file(path) == len(good.split("\n"))
    with pytest.raises(InputError, match="ends with a newline"):
        check_vocabulary_file(path, final_newline=False)


@pytest.mark.parametrize("edit, needle", [
    (lambda g: g.replace("\n0 ", "\n999999 ", 1), ":2: parent id 999999 must be a node before this one (0..0)"),
    (lambda g: g.split("\n")[0] + "\n" + "\n".join(["hello vocabulary, this is garbage"] * 5),
     ":2: expected 35 fields"),
    (lambda g: "20 10 0 0" + g[g.index("\n"):], ":1: k = 20, L = 10 makes ORB-SLAM3's loader reserve"),
    (lambda g: "10 8 0 0" + g[g.index("\n"):], "24.9 GB"),
    (lambda g: "1 6 0 0" + g[g.index("\n"):], "k = 1 is out of range (2..20)"),
    (lambda g: "2 2 0 0\n" + "\n".join([_line(0, 1)] * 3), ":1: node 0 has 3 children, more than k = 2"),
    (lambda g: g.replace("\n0 0 ", "\n0 2 ", 1), "isLeaf must be 0 or 1, got 2"),
    (lambda g: "2 1 0 0\n" + _line(0, 1, 256), ":2: descriptor bytes must be 0..255"),
    (lambda g: g.rsplit(" ", 1)[0] + " nan", "weight nan is not finite"),
    (lambda g: g.replace("\n", "\n\n", 2).replace("\n\n", "\n", 1), "an empty line"),
    (lambda g: "2 1 0 0\n" + _line(0, 0) + "\n" + _line(1, 1), ":3: the node is deeper than L = 1"),
    (lambda g: "2 2 0 0\n" + _line(0, 1) + "\n" + _line(0, 0), ":3: isLeaf is 0 but the node has no children"),
    (lambda g: "2 2 0 0\n" + _line(0, 1) + "\n" + _line(1, 1), ":3: parent 1 is marked as a leaf"),
    (lambda g: "2 1 0 0\n" + _line(0, 1, 1.5), "must be whole numbers"),
    (lambda g: "2 1 0 0\n" + "\n".join([_line(0, 1)] * 3), "more nodes than a tree of k = 2, L = 1 holds (2 below"),
    (lambda g: "3 2 0 0", "has a header but no nodes"),
])
def test_what_orbslam3_would_crash_on_or_misread_is_refused_naming_the_line(tmp_path, good, edit, needle):
    path = tmp_path / "voc.txt"
    path.write_text(edit(good))
    with pytest.raises(InputError, match="^vocabulary: ") as refused:
        check_vocabulary_file(path)
    assert str(path) in str(refused.value) and needle in str(refused.value), str(refused.value)


def test_binary_garbage_is_shown_as_a_short_printable_prefix(tmp_path):
    rng = np.random.default_rng(0)
    path = tmp_path / "voc.txt"
    path.write_bytes(b"10 6 0 0\n" + bytes(rng.integers(0, 256, 5000, dtype=np.uint8)).replace(b"\n", b"x"))
    with pytest.raises(InputError) as refused:
        check_vocabulary_file(path)
    message = str(refused.value)
    assert message.isprintable() and len(message) < 300 and ":2: a line longer than 1024 bytes" in message
    path.write_bytes(b"\x7fELF\x02\x01\x01\x00" + bytes(200))
    with pytest.raises(InputError, match=r"not a DBoW2 text vocabulary .*; its first line is b'\\x7fELF") as refused:
        check_vocabulary_file(path)
    assert str(refused.value).isprintable()


def test_a_large_file_is_checked_a_block_at_a_time(tmp_path):
    """A full k = 10, L = 4 tree (11,110 nodes) repeated past the node bound: refused at the line
    that exceeds it, fast, without holding the file."""
    k, levels = 10, 4
    parents = [-1]
    for level in range(levels):
        first = len(parents) - k ** level
        parents += [p for p in range(first, first + k ** level) for _ in range(k)]
    lines = ["10 4 0 0"] + [_line(p, int(i >= len(parents) - k ** levels)) for i, p in enumerate(parents) if i]
    path = tmp_path / "voc.txt"
    path.write_text("\n".join(lines))
    t0 = time.perf_counter()
    assert check_vocabulary_file(path) == len(parents) == 11111
    with open(path, "a") as f:  # 12 MB more of nodes than the tree holds
        for _ in range(8):
            f.write("\n" + "\n".join(lines[1:]))
    tracemalloc.start()
    with pytest.raises(InputError, match=":11112: more nodes than a tree of k = 10, L = 4 holds"):
        check_vocabulary_file(path)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 60e6 and time.perf_counter() - t0 < 10


def test_a_fifo_is_refused_without_waiting_for_a_writer(tmp_path):
    import os

    os.mkfifo(tmp_path / "voc.txt")
    with pytest.raises(InputError, match="named pipe"):
        check_vocabulary_file(tmp_path / "voc.txt")


def test_the_loaders_reservation_bounds_k_and_l():
    assert loader_size_problem(10, 6) is None and loader_size_problem(10, 7) is None  # ORBvoc.txt's, and 2.5 GB
    assert loader_size_problem(20, 5) is None
    assert "vector::reserve" in loader_size_problem(20, 10)
    assert "GB" in loader_size_problem(20, 6) and "GB" in loader_size_problem(10, 8)


@pytest.mark.parametrize("options, needle", [
    (["--k", "20", "--levels", "10"], "--k 20 --levels 10: k = 20, L = 10 makes ORB-SLAM3's loader reserve"),
    (["--k", "10", "--levels", "8"], "choose a smaller --k or --levels"),
    (["--features", "100000000"], "--features must be a whole number from 1 to 20000"),
    (["--features", "0"], "got 0"),
])
def test_build_refuses_what_orbslam3_cannot_load_before_rendering(tmp_path, capsys, monkeypatch, options, needle):
    from longslam.sim import simulate as recording

    monkeypatch.setattr(recording, "rendered_sequence", lambda *a, **k: pytest.fail("rendered before the options were checked"))
    out = tmp_path / "voc.txt"
    assert main(["vocabulary", "build", "--route", "demo", "--out", str(out), *options]) == 2
    one_line_error(capsys, needle)
    assert not out.exists()
