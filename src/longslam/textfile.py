"""Reading small text files (lists, trajectories, routes) with errors that name the file."""

from __future__ import annotations

from pathlib import Path

from longslam.errors import InputError


def read_text(path: Path, what: str, hint: str = "") -> str:
    """The file's text; a missing or unreadable file is an InputError naming `what` and the path."""
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{what} {path} does not exist{f' ({hint})' if hint else ''}") from None
    except (OSError, UnicodeDecodeError) as err:
        raise InputError(f"{what} {path} cannot be read: {err}") from None
