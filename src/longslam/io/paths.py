"""Checks on output locations, made before any work so that a bad `--out` fails at once."""

from __future__ import annotations

import os
from pathlib import Path

from longslam.core.errors import InputError
from longslam.core.file_kinds import special_file_kind

PLOT_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg")  # what the figures can be saved as


def check_output_folder(path: str | Path, what: str = "output folder") -> Path:
    """Refuse a folder path that cannot be written: a file or a symbolic link at `path`, a file
    among its parents, or a nearest existing parent that is not writable. Returns the path."""
    path = Path(path)
    if path.is_symlink():
        raise InputError(f"{what} {path} is a symbolic link; give the path of a folder")
    if path.exists() and not path.is_dir():
        raise InputError(
            f"{what} {path} is {special_file_kind(path) or 'a file'}; expected a folder "
            "(or a path that does not exist yet)"
        )
    for parent in path.absolute().parents:
        if parent.exists() or parent.is_symlink():
            if not parent.is_dir():
                raise InputError(f"{what} {path}: {parent} is a file, so no folder can be made under it")
            if not os.access(parent, os.W_OK | os.X_OK):
                raise InputError(f"{what} {path}: the folder {parent} is not writable")
            break
    return path


def check_output_file(path: str | Path, suffixes: tuple[str, ...], what: str = "output file") -> Path:
    """Refuse a file path whose folder does not exist, that is a folder, or whose extension is not
    one of `suffixes` (e.g. (".png", ".pdf"))."""
    path = Path(path)
    if path.suffix.lower() not in suffixes:
        raise InputError(f"{what} {path}: expected a file ending in {', '.join(suffixes)}")
    if path.is_dir():
        raise InputError(f"{what} {path} is a folder; expected a file path")
    if not path.absolute().parent.is_dir():
        raise InputError(f"{what} {path}: the folder {path.absolute().parent} does not exist")
    return path
