"""Which code made a run: longslam's version and, in a git checkout, its commit (marked dirty if
the checkout's sources differ from it), so that a published number can name the commit."""

from __future__ import annotations

import subprocess
from functools import lru_cache
from pathlib import Path

import longslam

SOURCE_ROOT = Path(longslam.__file__).resolve().parents[2]  # the checkout, for an editable install


@lru_cache(maxsize=1)
def source_commit() -> str | None:
    """The checkout's commit ('abc1234', or 'abc1234+dirty' with changes under src/ or plugins/);
    None outside a git checkout (an installed wheel) or without git."""

    def run(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(["git", "-C", str(SOURCE_ROOT), *args], capture_output=True, text=True, timeout=10)

    try:
        head = run("rev-parse", "--short=7", "HEAD")
        if head.returncode != 0:
            return None
        dirty = run("status", "--porcelain", "--untracked-files=no", "--", "src", "plugins").stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return head.stdout.strip() + ("+dirty" if dirty else "")


def provenance() -> dict[str, str | None]:
    return {"longslam_version": longslam.__version__, "longslam_commit": source_commit()}
