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

from longslam.core.errors import InputError
from longslam.vocabulary.dbow2 import check_vocabulary_file as check_text_vocabulary


def check_vocabulary_file(path: Path, what: str) -> None:
    """pyorbslam3 0.1.1 hands ORB-SLAM3 any file, which then "loads" garbage and tracks with it,
    or crashes (a parent id it has not read yet, a header whose tree it cannot reserve): the whole
    file is checked first, a line at a time (see longslam's `check_vocabulary_file`)."""
    check_text_vocabulary(path, what, final_newline=True)  # ORBvoc.txt ends with a newline


def _user_file(given: str, what: str, source: str) -> tuple[str, dict[str, Any]]:
    path = Path(given).expanduser()
    if not path.is_file():
        from longslam.core.file_kinds import special_file_kind

        problem = "a folder" if path.is_dir() else special_file_kind(path) or "no such file"
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
