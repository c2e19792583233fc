"""The front end under the SLAM methods: per-frame planar motion from wheel odometry and depth
scans, and the full-rate smoother that gives the final trajectory."""

from longslam.slam.frontend.motion import MODES, FrameStep, FrontEnd, FrontEndConfig, MethodDepths

__all__ = ["MODES", "FrameStep", "FrontEnd", "FrontEndConfig", "MethodDepths"]
