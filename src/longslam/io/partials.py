"""Temporary folders of killed processes: `.NAME.partial-PID@HOST[-...]` siblings whose PID is gone.

Output is written under such a name and renamed when complete (see `longslam.io.atomic`); a
process killed outright (SIGKILL, out of memory) cannot remove its own, so the next writer into
the same folder does: at once for a partial of this machine whose process is gone; one of another
machine (on a shared disk) only once nobody has touched it for a day, since its PID means nothing
here. Names without a host (written by earlier versions) keep the older rule: PID gone and idle a minute.
"""

from __future__ import annotations

import os
import re
import shutil
import socket
import time
from pathlib import Path

_PARTIAL = re.compile(r"^\..+\.partial-(?P<pid>\d+)(@(?P<host>[A-Za-z0-9_.]*))?(-[^/]*)?$")


def host_tag() -> str:
    """This machine's name as it goes into a partial's name (no '-', '@' or '/')."""
    return re.sub(r"[^A-Za-z0-9_.]", "_", socket.gethostname()) or "localhost"


def partial_path(path: str | Path, pid: int | None = None) -> Path:
    """The temporary sibling a process (this one by default) writes `path` under."""
    path = Path(path)
    return path.with_name(f".{path.name}.partial-{os.getpid() if pid is None else pid}@{host_tag()}")


def process_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process: alive
        return True
    return True


# A partial touched this recently is left alone even if its PID is gone here: on a folder shared
# between machines (NFS) the PID may be another machine's live writer.
IDLE_SECONDS = 60.0
OTHER_HOST_IDLE_SECONDS = 24 * 3600.0


def clean_stale_partials(folder: str | Path, idle_seconds: float = IDLE_SECONDS) -> list[Path]:
    """Remove the partial files and folders in `folder` whose writing process is gone (and that
    no one has modified for `idle_seconds`); returns them.

    A partial of a live process (this one's too) is left alone, as is anything not named like one.
    """
    folder = Path(folder)
    removed: list[Path] = []
    try:
        entries = list(folder.iterdir())
    except OSError:  # no folder yet, or not readable: nothing of ours there
        return removed
    here = host_tag()
    for path in entries:
        match = _PARTIAL.match(path.name)
        if match is None:
            continue
        host = match["host"]
        if host == here:  # our own machine: the PID tells
            if process_alive(int(match["pid"])):
                continue
        elif host is not None:  # another machine's: its PID cannot be checked from here
            if _recently_modified(path, OTHER_HOST_IDLE_SECONDS):
                continue
        elif process_alive(int(match["pid"])) or _recently_modified(path, idle_seconds):
            continue
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
        removed.append(path)
    return removed


def _recently_modified(path: Path, seconds: float) -> bool:
    try:
        return time.time() - path.lstat().st_mtime < seconds
    except OSError:  # removed meanwhile
        return True
