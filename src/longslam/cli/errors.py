"""How the `longslam` command reports failures it expects: one line, no traceback.

Expected: longslam's own errors (bad input), the operating system's (a full disk, a file size
limit, a missing permission) and SQLite's. Anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import errno
import os
import sqlite3
import sys

from longslam.core.errors import LongslamError

EXPECTED_FAILURES = (LongslamError, OSError, sqlite3.Error)

_FULL = {errno.ENOSPC, errno.EFBIG, getattr(errno, "EDQUOT", errno.ENOSPC)}


def describe_failure(err: BaseException, out: str | None = None) -> str:
    """One line naming what failed and, for a write, which file (or at least which output)."""
    if isinstance(err, LongslamError):
        return str(err)
    if isinstance(err, OSError):
        what = err.strerror or str(err)
        if err.errno in _FULL:
            what += " (the disk is full, or a file size limit such as `ulimit -f` was reached)"
        if err.filename is not None:
            other = f" -> {err.filename2}" if err.filename2 is not None else ""
            return f"{err.filename}{other}: {what}"
        return f"writing {out}: {what}" if out else what
    return f"{err}" + (f" (writing {out})" if out else "")


def quiet_broken_pipe() -> int:
    """The reader of our output went away (`longslam evaluate ... | head`): stop quietly, as
    command-line tools do, with the status of a process ended by SIGPIPE."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # so the interpreter's final flush cannot fail again
    except (OSError, ValueError):
        pass
    return 128 + 13
