"""longslam's default ORB vocabulary: built once into the cache from the `annex` building.

A vocabulary trained on the building a run evaluates would tune appearance-based loop closure to
the test route; this one never sees `university` (or a user's building). It is the vocabulary a
DBoW2 system (the `orbslam3` plugin) loads when the user names none.
"""

from __future__ import annotations

import fcntl
import hashlib
import logging
import time
from pathlib import Path
from typing import Any

from longslam.core.errors import InputError
from longslam.sim.routes import get_route
from longslam.sim.simulate import cache_root

log = logging.getLogger(__name__)
# While another process builds the default vocabulary (minutes), a waiting run says so this often.
WAIT_NOTE_S = 30.0

ROUTE = "annex-tour"  # 401 m in world annex
K = 10
LEVELS = 5
SEED = 0
EVERY = 2  # every 2nd of the route's 2,700 frames: neighbours add little but time
FEATURES = 1000


def default_vocabulary_path() -> Path:
    return cache_root() / "vocabulary" / f"{ROUTE}-k{K}-L{LEVELS}-seed{SEED}-every{EVERY}.txt"


def default_vocabulary(progress: bool = True) -> tuple[Path, dict[str, Any]]:
    """(path, provenance) of the default vocabulary, built on first use (about a minute on two
    cores, rendering included). Concurrent runs wait for one build instead of each making one."""
    from longslam.vocabulary.build import build_vocabulary_file, rendered_route

    path = default_vocabulary_path()
    route = get_route(ROUTE)
    info = {
        "world": route.world,
        "route": ROUTE,
        "k": K,
        "levels": LEVELS,
        "seed": SEED,
        "frames_every": EVERY,
        "features": FEATURES,
        "path": str(path),
        "trained_on_evaluated_world": False,
    }
    if path.is_file() and _intact(path):
        return path, info
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path.with_suffix(".lock"), "w") as lock:
        _wait_for(lock, path)
        if path.is_file() and not _intact(path, warn=False):  # warned of above
            # longslam's own cache file, damaged (a disk error, a hand edit): built again, not
            # handed to ORB-SLAM3, which crashes or tracks with garbage on a broken tree
            path.unlink()
            _digest_path(path).unlink(missing_ok=True)
        if not path.is_file():
            sequence = rendered_route(route, progress=progress)
            build_vocabulary_file(
                sequence, path, k=K, levels=LEVELS, seed=SEED, features=FEATURES, every=EVERY, progress=progress
            )
            _intact(path)  # checks it once and records its digest
    return path, info


def _digest_path(path: Path) -> Path:
    return path.with_name(path.name + ".sha256")


def _intact(path: Path, warn: bool = True) -> bool:
    """Whether the cached vocabulary is whole: its SHA-256 (30 ms) against the one recorded when it
    was first checked, or, without a record, the full check of `check_vocabulary_file` (about a
    second), which records it. A damaged file is warned of."""
    from longslam.io.atomic import write_text_atomic
    from longslam.vocabulary.dbow2 import check_vocabulary_file

    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    record = _digest_path(path)
    try:
        recorded = record.read_text(encoding="utf-8").strip()
    except (OSError, UnicodeDecodeError):
        recorded = ""
    if recorded:
        if recorded == digest.hexdigest():
            return True
        if warn:
            log.warning(
                f"warning: the cached default vocabulary {path} has changed since it was built "
                f"(its SHA-256 is not the one in {record.name}); building it again"
            )
        return False
    try:
        check_vocabulary_file(path, "the cached default vocabulary")
    except InputError as err:
        if warn:
            log.warning(f"warning: {err}; building it again")
        return False
    write_text_atomic(record, digest.hexdigest() + "\n")
    return True


def _wait_for(lock, path: Path) -> None:
    """Take the build lock; while another process holds it (building, for minutes), say so at
    once and every WAIT_NOTE_S, so a run does not sit silent."""
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return
    except BlockingIOError:
        pass
    start = last = time.monotonic()
    log.warning(
        f"note: another process is building the default vocabulary {path}; waiting for it "
        "(a build takes a few minutes)"
    )
    while True:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            break
        except BlockingIOError:
            time.sleep(0.2)
        if time.monotonic() - last >= WAIT_NOTE_S:
            last = time.monotonic()
            log.warning(f"note: still waiting for the default vocabulary ({last - start:.0f} s)")
    log.warning(f"note: the default vocabulary is ready after {time.monotonic() - start:.0f} s of waiting")
