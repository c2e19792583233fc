"""What the `longslam` command prints besides its results, set by `-v`, `--quiet`, `--no-progress`.

Results go to stdout whatever the level. On stderr: warnings and errors always; notes (`note: ...`)
unless `--quiet`; the library's log messages (the `longslam` logger) from `-v` (INFO) or `-vv`
(DEBUG); progress bars only on a terminal and without `--quiet` / `--no-progress`.
"""

from __future__ import annotations

import argparse
import logging
import sys

from longslam.core import progress

_quiet = False


class _Stderr(logging.StreamHandler):
    """A handler on whatever sys.stderr is when a message comes (a run swaps it, a test captures it)."""

    @property  # type: ignore[override]
    def stream(self):
        return sys.stderr

    @stream.setter
    def stream(self, value) -> None:
        pass


def configure(args: argparse.Namespace) -> None:
    global _quiet
    _quiet = bool(getattr(args, "quiet", False))
    verbose = getattr(args, "verbose", None) or 0
    level = logging.ERROR if _quiet else {0: logging.WARNING, 1: logging.INFO}.get(verbose, logging.DEBUG)
    logger = logging.getLogger("longslam")
    logger.setLevel(level)
    if not logger.handlers:
        handler = _Stderr()
        handler.setFormatter(logging.Formatter("%(message)s"))
        logger.addHandler(handler)
    progress.set_enabled(progress.for_terminal(sys.stderr, not (_quiet or getattr(args, "no_progress", False))))


def note(text: str) -> None:
    """A `note: ...` line on stderr, unless --quiet."""
    if not _quiet:
        print(f"note: {text}", file=sys.stderr)
