"""The `command` method: any program that reads a TUM RGB-D folder and writes a trajectory, run
as a longslam method (`CommandMethod`, `CommandConfig`)."""

from longslam.slam.command.config import CommandConfig
from longslam.slam.command.method import CommandMethod

__all__ = ["CommandConfig", "CommandMethod"]
