"""What a path is when it is not a regular file or a folder, for messages that refuse it."""

from __future__ import annotations

import os
import stat
from pathlib import Path


def special_file_kind(path: str | Path) -> str | None:
    """What `path` is if it exists and is neither a regular file nor a folder (through symbolic
    links): "a named pipe (FIFO)", "a character device", ...; None otherwise. Only stat is called:
    opening a FIFO blocks, and opening a device may act on it."""
    try:
        mode = os.stat(path).st_mode
    except OSError:  # missing, or a dangling link: nothing there to lose
        return None
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return None
    for test, kind in (
        (stat.S_ISFIFO, "a named pipe (FIFO)"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return kind
    return "not a regular file"
