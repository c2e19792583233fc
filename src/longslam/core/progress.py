"""Progress bars, one switch for all of them.

Every bar longslam draws (rendering, a method's frames, a study's runs, export and import, a
vocabulary) comes from `bar`, so the command line can turn them all off at once: `--no-progress`
or `--quiet`, and whenever stderr is not a terminal, since a bar redrawn with carriage returns
fills a redirected log with one line per update. Library callers keep tqdm's own behaviour until
they call `set_enabled`.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable
from typing import Any

from tqdm import tqdm

_enabled: bool | None = None  # None: not decided here (tqdm draws unless a caller disables it)


def set_enabled(enabled: bool | None) -> None:
    """True or False: every bar from now on is drawn or not; None: back to the callers' choice."""
    global _enabled
    _enabled = enabled


def for_terminal(stream: Any = None, wanted: bool = True) -> bool:
    """Whether bars should be drawn on `stream` (stderr by default): only if wanted and a terminal."""
    stream = sys.stderr if stream is None else stream
    try:
        return wanted and bool(stream.isatty())
    except (AttributeError, ValueError, OSError):  # a closed or replaced stream
        return False


def setting() -> bool | None:
    """What `set_enabled` was last given (None: never), to hand on to another process."""
    return _enabled


def enabled() -> bool:
    return _enabled is not False


def bar(iterable: Iterable[Any] | None = None, *, disable: bool = False, **options: Any) -> tqdm:
    """A tqdm bar (same arguments), not drawn when bars are switched off."""
    return tqdm(iterable, disable=disable or not enabled(), **options)
