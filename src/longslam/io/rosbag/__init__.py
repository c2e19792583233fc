"""A sequence as a ROS bag and back (`longslam export`, `longslam import`), through the pure-Python
`rosbags` library (the optional extra `longslam[ros]`).

- `conventions.py`: topics, frames, encodings, the clock offset and the odometry covariance;
- `messages.py`: building and reading the ROS messages (ROS 1 and ROS 2 spell fields differently);
- `tf.py`: a small TF buffer of the bag's /tf and /tf_static;
- `export.py`: sequence folder -> bag;
- `import_.py`: bag -> sequence folder.
"""

from __future__ import annotations

import importlib.util

from longslam.core.errors import InputError


def require_rosbags() -> None:
    """Refuse clearly when the optional dependency is missing."""
    if importlib.util.find_spec("rosbags") is None:
        raise InputError(
            "ROS bags need the rosbags package: pip install 'longslam[ros]' "
            "(or the version pinned in requirements.lock)"
        )
