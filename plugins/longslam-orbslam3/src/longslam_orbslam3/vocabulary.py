"""Which ORB vocabulary ORB-SLAM3 loads: the user's, or longslam's default.

ORB-SLAM3's own `ORBvoc.txt` comes from GitHub, out of reach of many machines; longslam builds
DBoW2 vocabularies of its own (`longslam vocabulary build`, MIT). The default is trained on the
`annex` building, never on the building a run evaluates, so appearance-based loop closure is not
tuned to the test route.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from longslam.errors import InputError


def check_vocabulary_file(path: Path, what: str) -> None:
    """A DBoW2 text vocabulary begins `k L scoring weighting` and has a line per node. pyorbslam3
    0.1.1 hands ORB-SLAM3 any file, which then "loads" garbage and tracks with it: check first."""
    try:
        with open(path, "rb") as f:
            header = f.readline().decode("ascii", errors="replace").split()
            nodes = sum(1 for _ in f)
    except OSError as err:
        raise InputError(f"{what}: cannot read {path} ({err.strerror})") from None
    expected = "a DBoW2 text vocabulary (first line 'k L scoring weighting', e.g. '10 6 0 0' as ORBvoc.txt)"
    if len(header) != 4 or not all(h.lstrip("-").isdigit() for h in header):
        raise InputError(f"{what}: {path} is not {expected}; its first line is {' '.join(header)[:60]!r}")
    k, levels, scoring, weighting = (int(h) for h in header)
    if not (2 <= k <= 20 and 1 <= levels <= 10 and 0 <= scoring <= 5 and 0 <= weighting <= 3):
        raise InputError(f"{what}: {path}: header {k} {levels} {scoring} {weighting} is out of range for {expected}")
    if nodes < k:
        raise InputError(f"{what}: {path} has {nodes} node lines; a vocabulary with k = {k} has at least {k}")


def _user_file(given: str, what: str, source: str) -> tuple[str, dict[str, Any]]:
    path = Path(given).expanduser()
    if not path.is_file():
        problem = "a folder" if path.is_dir() else "no such file"
        raise InputError(f"{what}: {problem} (expected a DBoW2 text vocabulary such as ORBvoc.txt)")
    check_vocabulary_file(path, what)
    return str(path.resolve()), {"source": source, "path": str(path.resolve())}


def resolve_vocabulary(parameter: str) -> tuple[str, dict[str, Any]]:
    """(path, provenance): `--param vocabulary=PATH`, else $PYORBSLAM3_VOCAB, else longslam's default."""
    if parameter:
        return _user_file(parameter, f"method 'orbslam3': vocabulary={parameter!r}", "parameter")
    env = os.environ.get("PYORBSLAM3_VOCAB")
    if env:
        return _user_file(env, f"PYORBSLAM3_VOCAB={env!r}", "PYORBSLAM3_VOCAB")
    from longslam.vocabulary import default_vocabulary

    path, info = default_vocabulary()
    return str(path), {"source": "longslam default", **info}
