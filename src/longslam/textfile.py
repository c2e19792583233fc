"""Reading small text files (lists, trajectories, routes) with errors that name the file."""

from __future__ import annotations

from pathlib import Path

from longslam.errors import InputError


def read_text(path: Path, what: str, hint: str = "", encoding: str = "utf-8",
              error: type[InputError] = InputError) -> str:
    """The file's text; a missing or unreadable file is an `error` (an InputError) naming `what`
    and the path."""
    try:
        return path.read_text(encoding=encoding)
    except FileNotFoundError:
        raise error(f"{what} {path} does not exist{f' ({hint})' if hint else ''}") from None
    except (OSError, UnicodeDecodeError) as err:
        raise error(f"{what} {path} cannot be read: {err}") from None
