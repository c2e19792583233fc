"""A run's native console: what C and C++ code inside a method prints goes to a log file.

A wrapped C++ system (ORB-SLAM3, say) writes to the process's file descriptors 1 and 2 from its
own threads, at any time; its lines would bury the progress bar and the run's own messages. For
the length of a run the engine points both descriptors at the run folder's `console.log`, and
keeps Python's own `sys.stdout` / `sys.stderr` (progress, warnings, errors) on the terminal by
giving them streams on copies of the original descriptors.
"""

from __future__ import annotations

import io
import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

CONSOLE_LOG = "console.log"


def _fd_of(stream: object) -> int | None:
    try:
        return stream.fileno()  # type: ignore[attr-defined]
    except (AttributeError, OSError, ValueError, io.UnsupportedOperation):
        return None


@contextmanager
def native_output_to(path: str | Path) -> Iterator[Path]:
    """Descriptors 1 and 2 into `path` (appended) until the block ends; the log is removed at the
    end if nothing was written to it."""
    path = Path(path)
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, OSError, ValueError):
            pass
    log_fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    saved = {fd: os.dup(fd) for fd in (1, 2)}
    # Python streams that write to descriptor 1 or 2 are swapped for streams on the saved copies.
    # Streams that are not on those descriptors (pytest's capsys, a notebook) are left alone.
    swapped: dict[str, object] = {}
    for name, fd in (("stdout", 1), ("stderr", 2)):
        stream = getattr(sys, name)
        if _fd_of(stream) == fd:
            swapped[name] = stream
            replacement = os.fdopen(
                os.dup(saved[fd]),
                "w",
                buffering=1,
                encoding=getattr(stream, "encoding", None),
                errors=getattr(stream, "errors", None),
            )
            setattr(sys, name, replacement)
    try:
        os.dup2(log_fd, 1)
        os.dup2(log_fd, 2)
        yield path
    finally:
        for name, original in swapped.items():
            replacement = getattr(sys, name)
            try:
                replacement.flush()
            finally:
                setattr(sys, name, original)
                replacement.close()
        os.dup2(saved[1], 1)
        os.dup2(saved[2], 2)
        for fd in (*saved.values(), log_fd):
            os.close(fd)
        try:
            if path.stat().st_size == 0:
                path.unlink()
        except FileNotFoundError:
            pass
