"""Reading a rerun recording back, for the live-view tests."""

from __future__ import annotations

from pathlib import Path


def rows(path: Path, entity: str, column: str) -> list:
    """Every value logged to `entity`'s `column`, in the order logged."""
    from rerun.chunk import RrdReader  # the callers skip themselves where rerun is not installed

    out = []
    for chunk in RrdReader(path).stream():
        if chunk.entity_path == entity:
            batch = chunk.to_record_batch()
            if column in batch.schema.names:
                out += batch.column(column).to_pylist()
    return out
