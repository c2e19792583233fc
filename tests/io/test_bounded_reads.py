"""Trajectory files and stdin are read a block at a time and refused as soon as they are not a
trajectory: `evaluate - gt.txt < /dev/zero` and `evaluate /dev/zero SEQ` read until MemoryError."""

from __future__ import annotations

import json
import os
import signal
import sys
import threading
from pathlib import Path

import pytest

from helpers.cli_checks import one_line_error
from helpers.tiny_sequences import write_tiny_sequence
from longslam.cli.main import main


@pytest.fixture()
def seq(tmp_path) -> Path:
    return write_tiny_sequence(tmp_path / "seq", n=12)[0]


class _Endless:
    """A stdin that never ends: `block` over and over, to whoever reads it in bounded blocks."""

    def __init__(self, block: bytes):
        self.block, self.given = block, 0

    def read(self, size: int = -1) -> bytes:
        if size is None or size < 0:
            pytest.fail("stdin was read whole: it never ends")
        self.given += size
        return (self.block * (size // len(self.block) + 1))[:size]


class _Stdin:
    def __init__(self, stream: _Endless):
        self.buffer = stream

    def read(self, size: int = -1) -> str:
        return self.buffer.read(size).decode("latin-1")


def test_stdin_of_nul_bytes_is_refused_at_once(seq, capsys, monkeypatch):
    zeros = _Endless(b"\0")
    monkeypatch.setattr(sys, "stdin", _Stdin(zeros))
    assert main(["evaluate", "-", str(seq / "groundtruth.txt")]) == 2
    one_line_error(capsys, "<stdin>:1", "a NUL byte", "expected text")
    assert zeros.given <= 1 << 20


def test_stdin_that_never_ends_is_refused_past_the_size_bound(seq, capsys, monkeypatch):
    from longslam.io import trajectory_files

    monkeypatch.setattr(trajectory_files, "MAX_TRAJECTORY_BYTES", 5 * 10**6)
    lines = _Endless(b"0.1 0 0 0 0 0 0 1\n")
    monkeypatch.setattr(sys, "stdin", _Stdin(lines))
    assert main(["evaluate", "-", str(seq / "groundtruth.txt")]) == 2
    one_line_error(capsys, "trajectory file <stdin> is larger than 5 MB")
    assert lines.given <= 6 * 10**6


def test_a_device_is_refused_before_it_is_opened(seq, capsys, nothing_under_dev):
    assert main(["evaluate", "/dev/zero", str(seq)]) == 2
    one_line_error(capsys, "trajectory file /dev/zero is a character device; expected a text file")


def test_a_long_line_or_a_nul_in_a_file_names_the_file_and_line(seq, tmp_path, capsys):
    truth = (seq / "groundtruth.txt").read_text().splitlines(keepends=True)
    long_line = tmp_path / "long.txt"
    long_line.write_text("".join(truth[:3]) + "1 " * 5000 + "\n" + "".join(truth[3:]))
    assert main(["evaluate", str(long_line), str(seq)]) == 2
    one_line_error(capsys, f"{long_line}:4", "a line longer than 4096 bytes")
    nul = tmp_path / "nul.txt"
    nul.write_bytes("".join(truth[:5]).encode() + b"0.5 \0\0\0\n")
    assert main(["evaluate", str(seq / "groundtruth.txt"), str(nul)]) == 2
    one_line_error(capsys, f"{nul}:6", "a NUL byte")


def test_a_pipe_is_read_once(seq, tmp_path, capsys):
    """As `evaluate <(cat trajectory.txt) SEQ` gives it: the format was found on a first read,
    and a second open of the pipe waited for a writer that had gone."""
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    text = (seq / "groundtruth.txt").read_bytes()

    def write_once():
        with open(fifo, "wb") as writer:
            writer.write(text)

    threading.Thread(target=write_once, daemon=True).start()

    def too_long(*_):
        raise TimeoutError("the pipe was opened a second time")

    previous = signal.signal(signal.SIGALRM, too_long)
    signal.alarm(20)
    try:
        assert main(["evaluate", str(fifo), str(seq), "--json"]) == 0
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    assert json.loads(capsys.readouterr().out)["ate"] == 0.0
