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


def machine() -> str:
    """This machine as a published page names it: cores, CPU model, memory, kernel."""
    import os
    import platform

    def first(path: str, key: str) -> str | None:
        try:
            lines = Path(path).read_text(encoding="utf-8", errors="replace").splitlines()
        except OSError:
            return None
        return next((line.split(":", 1)[1].strip() for line in lines if line.startswith(key)), None)

    model = first("/proc/cpuinfo", "model name") or platform.processor() or "unknown CPU"
    memory_kb = first("/proc/meminfo", "MemTotal")
    memory = f"{int(memory_kb.split()[0]) / 2**20:.0f} GiB memory" if memory_kb else "unknown memory"
    return f"{os.cpu_count()} cores ({model}), {memory}, {platform.system()} {platform.release()}"


def single_commit(commits: list[str | None], what: str) -> str:
    """The one clean commit that made every run of `what`; a ValueError naming the commits when
    they are several, unknown (a run made outside a git checkout) or dirty (uncommitted changes)."""
    made_by = sorted({c or "unknown" for c in commits})
    if not made_by:
        raise ValueError(f"{what}: no finished run to publish")
    if len(made_by) > 1 or made_by[0] == "unknown" or made_by[0].endswith("+dirty"):
        raise ValueError(
            f"{what}: the runs come from commits {', '.join(made_by)}; a page is published from runs of one "
            "clean commit: run them again at one commit (delete the step's work folder to start afresh)"
        )
    return made_by[0]
