"""Write files and folders under a temporary name, then rename, so no half-written output remains."""

from __future__ import annotations

import ctypes
import errno
import os
import shutil
import stat
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from longslam.core.errors import InputError
from longslam.core.file_kinds import special_file_kind
from longslam.io.partials import partial_path

_AT_FDCWD, _RENAME_NOREPLACE = -100, 1
# Text files are UTF-8 whatever the locale (under LANG=C without UTF-8 mode Python would write
# ASCII and fail on a path like `séquence`); a path that is not valid UTF-8 keeps its bytes.
PATH_BYTES = "surrogateescape"


@contextmanager
def atomic_path(
    path: str | Path, overwrite: bool = True, may_replace: Callable[[Path], None] | None = None
) -> Iterator[Path]:
    """Yield a temporary sibling path; on success rename it to `path`, on failure remove it.

    With `overwrite=False` an existing `path` is never replaced, even one that another process
    wrote while this one worked: the rename fails, this output is discarded, InputError is raised.
    With `overwrite=True`, `may_replace(path)` (if given) is called on an existing `path` just
    before it is replaced, and may raise to keep it (see `longslam.io.overwrite_policy`).
    """
    path = Path(path)
    tmp = partial_path(path)
    try:
        yield tmp
        if overwrite:
            if may_replace is not None and (path.exists() or path.is_symlink()):
                may_replace(path)
            _replace(tmp, path)
        else:
            try:
                rename_no_replace(tmp, path)
            except FileExistsError:
                raise InputError(
                    f"{path} was written by another process while this one ran; it was left as it is "
                    "and this output discarded (pass --overwrite to replace it)"
                ) from None
    except BaseException:
        if tmp.is_dir():
            shutil.rmtree(tmp, ignore_errors=True)
        elif tmp.exists():
            tmp.unlink()
        raise


def rename_no_replace(src: str | Path, dst: str | Path) -> None:
    """Rename `src` to `dst` atomically, or raise FileExistsError if `dst` exists (even a folder
    or file made a moment before by another process): Linux renameat2(RENAME_NOREPLACE)."""
    renameat2 = getattr(ctypes.CDLL(None, use_errno=True), "renameat2", None)
    if renameat2 is not None:
        if renameat2(_AT_FDCWD, os.fsencode(src), _AT_FDCWD, os.fsencode(dst), _RENAME_NOREPLACE) == 0:
            return
        code = ctypes.get_errno()
        if code == errno.EEXIST:
            raise FileExistsError(code, os.strerror(code), str(dst))
        if code not in (errno.ENOSYS, errno.EINVAL):  # EINVAL: a filesystem without the flag
            raise OSError(code, os.strerror(code), str(dst))
    # Elsewhere: a check, then a rename that refuses a non-empty folder anyway.
    if os.path.lexists(dst):
        raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST), str(dst))
    os.rename(src, dst)


def check_same_kind(tmp: Path, path: Path) -> None:
    """Refuse to put the output `tmp` in place of an existing `path` of another kind: a file
    replaces only a file (or a symbolic link), a folder only a folder. A FIFO or a device node is
    never replaced, whoever checked the path before: as root, os.replace over /dev/null would
    leave a regular file in its place."""
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return
    if stat.S_ISLNK(mode) and not tmp.is_dir():
        return  # the link itself is replaced, never what it points to
    if stat.S_ISDIR(mode) == tmp.is_dir() and (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
        return
    kind = (
        "a symbolic link"
        if stat.S_ISLNK(mode)
        else "a folder"
        if stat.S_ISDIR(mode)
        else special_file_kind(path) or "a file"
    )
    raise InputError(
        f"{path} is {kind}, not a {'folder' if tmp.is_dir() else 'regular file'} longslam may "
        "replace; it was left as it is and this output discarded"
    )


def replace_file(tmp: str | Path, path: str | Path) -> None:
    """os.replace(tmp, path) for a finished output file, refusing what `check_same_kind` refuses."""
    check_same_kind(Path(tmp), Path(path))
    os.replace(tmp, path)


def _replace(tmp: Path, path: Path) -> None:
    """Put `tmp` in place of `path`; an existing folder is moved aside first and removed after,
    so `path` is never missing its complete contents for longer than two renames."""
    check_same_kind(tmp, path)
    if not path.is_dir() or path.is_symlink():
        os.replace(tmp, path)
        return
    backup = path.with_name(f".{path.name}.old-{uuid.uuid4().hex[:12]}")
    os.rename(path, backup)
    try:
        os.rename(tmp, path)
    except BaseException:
        os.rename(backup, path)
        raise
    shutil.rmtree(backup, ignore_errors=True)


def write_text_atomic(path: str | Path, text: str) -> None:
    with atomic_path(path) as tmp, naming_the_file(path):  # the file the user asked for, not its partial
        Path(tmp).write_text(text, encoding="utf-8", errors=PATH_BYTES)


@contextmanager
def naming_the_file(path: str | Path) -> Iterator[None]:
    """An OSError from writing an open file (a full disk, `ulimit -f`) carries no file name:
    give it `path`, so the user learns which file could not be written."""
    try:
        yield
    except OSError as err:
        if err.filename is None:
            raise OSError(err.errno, err.strerror or str(err), str(path)) from err
        raise


def write_text(path: str | Path, text: str) -> None:
    with naming_the_file(path):
        Path(path).write_text(text, encoding="utf-8", errors=PATH_BYTES)


def write_bytes(path: str | Path, data: bytes) -> None:
    with naming_the_file(path):
        Path(path).write_bytes(data)


def name_final_folder(figures: Any, tmp: Path, out: Path) -> Any:
    """The figures with every path into the temporary folder `tmp` (a method's database, say)
    named by where it will be, in `out`, once the run folder is renamed."""
    prefix = str(tmp)

    def rename(value: Any) -> Any:
        if isinstance(value, str) and (value == prefix or value.startswith(prefix + "/")):
            return str(out) + value[len(prefix) :]
        if isinstance(value, dict):
            return {k: rename(v) for k, v in value.items()}
        if isinstance(value, (list, tuple)):
            return type(value)(rename(v) for v in value)
        return value

    return rename(figures)
