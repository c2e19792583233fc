"""Reading small text files (lists, trajectories, routes) with errors that name the file."""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import BinaryIO

from longslam.core.errors import InputError
from longslam.core.file_kinds import special_file_kind

_CHUNK = 1 << 20


def read_text(
    path: Path, what: str, hint: str = "", encoding: str = "utf-8", error: type[InputError] = InputError
) -> str:
    """The file's text; a missing or unreadable file is an `error` (an InputError) naming `what`
    and the path."""
    try:
        return path.read_text(encoding=encoding)
    except FileNotFoundError:
        raise error(f"{what} {path} does not exist{f' ({hint})' if hint else ''}") from None
    except (OSError, UnicodeDecodeError) as err:
        raise error(f"{what} {path} cannot be read: {err}") from None


def read_bounded_text(
    path: Path, what: str, max_bytes: int, max_line: int, stream: BinaryIO | None = None, name: str | None = None
) -> str:
    """The UTF-8 text of a file (or of `stream`, stdin say, `name` naming it), read a block at a
    time and refused as soon as it is not a text of this kind: a NUL byte, a line longer than
    `max_line` bytes, or more than `max_bytes` in all. So `/dev/zero`, or a stream that never
    ends, is a one-line error, not a read until memory runs out. A path that is a device or a
    socket is refused before it is opened; a FIFO (a pipe, `<(...)`) is read as a stream."""
    name = name or str(path)
    if stream is None:
        try:
            mode = os.stat(path).st_mode
        except FileNotFoundError:
            raise InputError(f"{what} {path} does not exist") from None
        except OSError as err:
            raise InputError(f"{what} {path} cannot be read: {err.strerror}") from None
        if not (stat.S_ISREG(mode) or stat.S_ISFIFO(mode)):
            kind = "a folder" if stat.S_ISDIR(mode) else special_file_kind(path) or "not a regular file"
            raise InputError(f"{what} {path} is {kind}; expected a text file")
        try:
            with open(path, "rb") as handle:
                return read_bounded_text(path, what, max_bytes, max_line, handle, name)
        except OSError as err:
            raise InputError(f"{what} {path} cannot be read: {err.strerror}") from None
    blocks: list[bytes] = []
    size, line, current = 0, 1, 0  # bytes so far, the line number and length of the line being read
    while True:
        block = stream.read(_CHUNK)
        if not block:
            break
        if isinstance(block, str):  # a text stream (sys.stdin replaced, in tests)
            block = block.encode("utf-8", "surrogateescape")
        size += len(block)
        if size > max_bytes:
            raise InputError(
                f"{what} {name} is larger than {max_bytes / 1e6:g} MB; expected a {what} "
                f"(stopped reading at line {line})"
            )
        nul = block.find(b"\0")
        if nul >= 0:
            at = line + block.count(b"\n", 0, nul)
            raise InputError(f"{what} {name}:{at}: a NUL byte; expected text")
        parts = block.split(b"\n")
        lengths = [current + len(parts[0])] + [len(p) for p in parts[1:]]
        longest = max(range(len(lengths)), key=lengths.__getitem__)
        if lengths[longest] > max_line:
            raise InputError(f"{what} {name}:{line + longest}: a line longer than {max_line} bytes; expected a {what}")
        line += len(parts) - 1
        current = lengths[-1]
        blocks.append(block)
    try:
        return b"".join(blocks).decode("utf-8")
    except UnicodeDecodeError as err:
        raise InputError(f"{what} {name} cannot be read: {err}") from None
