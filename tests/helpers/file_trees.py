"""A folder's files and their contents, to check that a refused command changed nothing."""

from __future__ import annotations

from pathlib import Path


def file_tree(path: Path) -> dict[str, bytes]:
    """Every file under `path` with its content: what must survive a refused command."""
    return {str(p.relative_to(path)): p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()}
