"""What `--overwrite` may replace: only an output of the same kind the command makes (a run
folder, a sequence, a bag, a file it writes), never one of the command's inputs, never a folder
holding one, never a folder of the user's own files.

Every check compares resolved real paths, so a symbolic link or `..` cannot hide that `--out` is
an input, lies inside one, or holds one.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from pathlib import Path

from longslam.core.errors import InputError
from longslam.core.file_kinds import special_file_kind

# What each kind of folder holds when longslam made it. A folder with anything else in it is not
# replaced: the extra entry may be the user's (a run kept inside a sequence, notes, a dataset).
SEQUENCE_ENTRIES = frozenset(
    {
        "rgb",
        "depth",
        "rgb.txt",
        "depth.txt",
        "groundtruth.txt",
        "odometry.txt",
        "camera.json",
        "meta.json",
    }
)
SEQUENCE_MARKERS = ("meta.json", "rgb.txt")
RUN_MARKERS = ("stats.json", "config.toml")
BAG_MARKERS = ("metadata.yaml",)
BAG_SUFFIXES = (".db3", ".db3-shm", ".db3-wal", ".mcap", ".zstd", ".yaml")
ROS1_MAGIC = b"#ROSBAG V2.0"

RUN, SEQUENCE, BAG, ROS1_BAG = "run folder", "sequence folder", "bag folder", "ROS 1 bag"


def _real(path: str | Path) -> Path:
    return Path(os.path.realpath(os.fspath(path)))


def check_not_an_input(
    out: str | Path, inputs: Mapping[str, str | Path | None], what: str, inside: bool = True
) -> None:
    """Refuse an output path that is one of the command's inputs, holds one, or (with `inside`)
    lies inside one.

    `inputs` maps a description ("input sequence") to a path; None entries are skipped."""
    target = _real(out)
    for label, given in inputs.items():
        if given is None:
            continue
        source = _real(given)
        # a label that names its path already ("input seq160") is not followed by it again
        named = label if label.endswith(f" {given}") else f"{label} {given}"
        if target == source:
            raise InputError(f"{what} {out} is the {named} itself; choose another --out")
        if target in source.parents:
            raise InputError(f"{what} {out} holds the {named}; writing there would delete it; " "choose another --out")
        if inside and source in target.parents:
            raise InputError(f"{what} {out} is inside the {named}; write beside the input, not into it")


def _entries(path: Path) -> list[str]:
    try:
        return sorted(os.listdir(path))
    except OSError as err:
        raise InputError(f"{path}: cannot be read to check what --overwrite would replace: {err.strerror}") from None


def _nested(path: Path, names: Iterable[str]) -> str | None:
    """A sub-folder of `path` holding a run, a sequence or a bag, which replacing `path` would lose."""
    for name in names:
        child = path / name
        if child.is_dir() and not child.is_symlink():
            for markers, kind in ((RUN_MARKERS, "a run"), (("rgb.txt",), "a sequence"), (BAG_MARKERS, "a bag")):
                if all((child / m).exists() for m in markers):
                    return f"{child} holds {kind}"
    return None


def why_not_replaceable(path: Path, kind: str) -> str | None:
    """None if `path` is an output of `kind` that longslam made and may replace; else the reason."""
    if path.is_symlink():
        return "it is a symbolic link"
    if kind == ROS1_BAG:
        if not path.is_file():
            return f"it is {special_file_kind(path) or 'a folder'}, not a file"
        try:
            with open(path, "rb") as handle:
                head = handle.read(len(ROS1_MAGIC))
        except OSError as err:
            return f"it cannot be read ({err.strerror})"
        return None if head == ROS1_MAGIC else "it is not a ROS 1 bag (no #ROSBAG V2.0 header)"
    if not path.is_dir():
        return f"it is {special_file_kind(path) or 'a file'}, not a {kind}"
    names = _entries(path)
    if kind == RUN:
        missing = [m for m in RUN_MARKERS if m not in names]
        if missing:
            return f"it is not a run folder (no {' and no '.join(missing)})"
        return _nested(path, names)
    if kind == SEQUENCE:
        missing = [m for m in SEQUENCE_MARKERS if m not in names]
        if missing:
            return f"it is not a sequence longslam wrote (no {' and no '.join(missing)})"
        extra = [n for n in names if n not in SEQUENCE_ENTRIES]
        if extra:
            return f"it holds files that are not a sequence's: {', '.join(extra[:5])}{' ...' if len(extra) > 5 else ''}"
        return None
    if kind == BAG:
        if "metadata.yaml" not in names:
            return "it is not a ROS 2 bag (no metadata.yaml)"
        extra = [n for n in names if not n.endswith(BAG_SUFFIXES)]
        if extra:
            return f"it holds files that are not a bag's: {', '.join(extra[:5])}{' ...' if len(extra) > 5 else ''}"
        return None
    raise ValueError(f"unknown kind of output {kind!r}")


def check_replaceable(out: str | Path, kind: str, overwrite: bool, what: str | None = None) -> None:
    """Refuse an existing `out` without `overwrite`, and with it anything but a `kind` longslam made."""
    out = Path(out)
    what = what or kind
    if not (out.exists() or out.is_symlink()):
        return
    if not overwrite:
        raise InputError(f"{what} {out} exists already; choose another path or pass --overwrite")
    reason = why_not_replaceable(out, kind)
    if reason is not None:
        raise InputError(
            f"{what} {out} exists and --overwrite replaces only a {kind} longslam made: {reason}; "
            "nothing was deleted; remove it yourself or choose another --out"
        )


def replace_guard(kind: str, what: str | None = None):
    """A check for `atomic_path(may_replace=...)`: the same rule at the moment of the rename, for a
    folder that appeared or changed while the command worked."""

    def guard(path: Path) -> None:
        check_replaceable(path, kind, True, what)

    return guard


# The first bytes of each kind of output file longslam writes, by suffix: --overwrite replaces an
# existing file of that kind only, not the user's notes saved as plan.png.
FILE_SIGNATURES: dict[str, tuple[str, tuple[bytes, ...]]] = {
    ".png": ("a PNG image", (b"\x89PNG\r\n\x1a\n",)),
    ".jpg": ("a JPEG image", (b"\xff\xd8\xff",)),
    ".jpeg": ("a JPEG image", (b"\xff\xd8\xff",)),
    ".pdf": ("a PDF file", (b"%PDF-",)),
    ".svg": ("an SVG image", (b"<?xml", b"<svg")),
    ".rrd": ("a rerun recording", (b"RRF",)),
}
VOCABULARY = "vocabulary"


def _looks_like_vocabulary(path: Path) -> bool:
    """A DBoW2 text vocabulary's header: 'k L scoring weighting', four whole numbers."""
    with open(path, "rb") as handle:
        header = handle.readline(200).split()
    return len(header) == 4 and all(h.lstrip(b"-").isdigit() for h in header)


def replaced_file_problem(path: Path, kind: str | None = None) -> str | None:
    """Why an existing regular file at `path` is not an output of the kind --overwrite replaces
    (`kind` VOCABULARY, or by its suffix, see FILE_SIGNATURES), or None if it is one (or of a kind
    not recognised by content)."""
    try:
        if kind == VOCABULARY:
            return (
                None
                if _looks_like_vocabulary(path)
                else "not a vocabulary (its first line is not 'k L scoring weighting')"
            )
        signature = FILE_SIGNATURES.get(path.suffix.lower())
        if signature is None:
            return None
        label, starts = signature
        with open(path, "rb") as handle:
            head = handle.read(64).lstrip() if path.suffix.lower() == ".svg" else handle.read(64)
    except OSError as err:
        return f"it cannot be read ({err.strerror})"
    if path.stat().st_size == 0 or head.startswith(starts):  # an empty file holds nothing to lose
        return None
    return f"not {label}"


def check_output_file_free(
    path: str | Path, overwrite: bool, what: str = "output file", kind: str | None = None
) -> None:
    """An existing file is replaced only with `overwrite`, and only if it is a file of the kind
    the command writes (see `replaced_file_problem`); a folder, a FIFO or a device never (as
    root, replacing /dev/null would leave a regular file in its place)."""
    path = Path(path)
    if path.is_dir():
        raise InputError(f"{what} {path} is a folder; expected a file path")
    special = special_file_kind(path)
    if special is not None:
        raise InputError(
            f"{what} {path} is {special}, not a regular file; longslam writes and --overwrite replaces "
            "only regular files; choose another path"
        )
    if (path.exists() or path.is_symlink()) and not overwrite:
        raise InputError(f"{what} {path} exists already; choose another path or pass --overwrite")
    problem = replaced_file_problem(path, kind) if path.is_file() else None
    if problem is not None:
        raise InputError(
            f"{what} {path} exists and --overwrite replaces only a file of the kind it writes: this one "
            f"is {problem}; nothing was replaced"
        )
