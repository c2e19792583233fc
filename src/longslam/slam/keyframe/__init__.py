"""The keyframe method (RTAB-Map's design): `KeyframeMethod`, `KeyframeConfig`."""

from longslam.slam.keyframe.config import KeyframeConfig
from longslam.slam.keyframe.method import KeyframeMethod

__all__ = ["KeyframeConfig", "KeyframeMethod"]
