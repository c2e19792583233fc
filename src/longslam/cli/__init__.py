"""The `longslam` command: the parser, one function per command, shell completion and output."""

from longslam.cli.main import main

__all__ = ["main"]
