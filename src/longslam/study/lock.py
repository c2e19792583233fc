"""One study at a time in a study folder: two studies writing one database and one `runs/` tree
would overwrite each other's runs (and record them all as failed)."""

from __future__ import annotations

import contextlib
import fcntl
import os
from collections.abc import Iterator
from pathlib import Path

from longslam.core.errors import InputError

LOCK_NAME = ".study.lock"


@contextlib.contextmanager
def study_lock(out: Path) -> Iterator[None]:
    """Hold the study folder `out` (which must exist) for this process, or stop at once with an
    error naming the process that holds it. The lock is the kernel's (flock), so a study that is
    killed releases it."""
    path = Path(out) / LOCK_NAME
    handle = open(path, "a+")
    try:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.seek(0)
            holder = handle.read().strip() or "unknown"
            raise InputError(
                f"study folder {out} is in use by another study (process {holder}); wait for it to end, "
                "or choose another --out"
            ) from None
        handle.seek(0)
        handle.truncate()
        handle.write(f"{os.getpid()}\n")
        handle.flush()
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)
    finally:
        handle.close()
