"""The path the README gives for opening a keyframe run's `memory.db`; the database lives in
`slam/keyframe/memory_db.py`."""

from longslam.slam.keyframe.memory_db import MemoryDatabase

__all__ = ["MemoryDatabase"]
