"""longslam's default ORB vocabulary: built once into the cache from the `annex` building.

A vocabulary trained on the building a run evaluates would tune appearance-based loop closure to
the test route; this one never sees `university` (or a user's building). It is the vocabulary a
DBoW2 system (the `orbslam3` plugin) loads when the user names none.
"""

from __future__ import annotations

import fcntl
from pathlib import Path
from typing import Any

from longslam.sim.simulate import cache_root
from longslam.sim.routes import get_route

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
    info = {"world": route.world, "route": ROUTE, "k": K, "levels": LEVELS, "seed": SEED, "frames_every": EVERY,
            "features": FEATURES, "path": str(path), "trained_on_evaluated_world": False}
    if path.is_file():
        return path, info
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not path.is_file():
            sequence = rendered_route(route, progress=progress)
            build_vocabulary_file(sequence, path, k=K, levels=LEVELS, seed=SEED, features=FEATURES, every=EVERY,
                                  progress=progress)
    return path, info
