"""Sensor models: the cached clean render turned into what a real RGB-D camera delivers."""

from longslam.sim.sensors.base import FrameMotion, SensorModel, frame_rng
from longslam.sim.sensors.catalog import IDEAL, get_sensor, sensor_names
from longslam.sim.sensors.colour import ColourNoise
from longslam.sim.sensors.kinect import KinectV1
from longslam.sim.sensors.realsense import RealSenseD435

__all__ = [
    "ColourNoise",
    "FrameMotion",
    "IDEAL",
    "KinectV1",
    "RealSenseD435",
    "SensorModel",
    "frame_rng",
    "get_sensor",
    "sensor_names",
]
