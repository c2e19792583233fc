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


def resolve_vocabulary(parameter: str) -> tuple[str, dict[str, Any]]:
    """(path, provenance): `--param vocabulary=PATH`, else $PYORBSLAM3_VOCAB, else longslam's default."""
    if parameter:
        path = Path(parameter).expanduser()
        if not path.is_file():
            raise InputError(f"method 'orbslam3': vocabulary={parameter!r}: no such file (expected a DBoW2 text vocabulary such as ORBvoc.txt)")
        return str(path.resolve()), {"source": "parameter", "path": str(path.resolve())}
    env = os.environ.get("PYORBSLAM3_VOCAB")
    if env:
        path = Path(env).expanduser()
        if not path.is_file():
            raise InputError(f"PYORBSLAM3_VOCAB={env!r}: no such file (expected a DBoW2 text vocabulary such as ORBvoc.txt)")
        return str(path.resolve()), {"source": "PYORBSLAM3_VOCAB", "path": str(path.resolve())}
    from longslam.vocabulary import default_vocabulary

    path, info = default_vocabulary()
    return str(path), {"source": "longslam default", **info}
