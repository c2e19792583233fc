"""Per-frame values of a fixed shape, appended one at a time into chunks of a flat array.

A list of one small numpy array per frame costs the array's header and allocation besides its
data, more than the 128 bytes of a 4 x 4 pose; a Python float in a list costs 32 bytes for 8.
Chunks of one flat array hold the data alone.
"""

from __future__ import annotations

import numpy as np

CHUNK = 4096


class Rows:
    """Rows of shape `shape` (float64), appended in order; `array()` gives them as (N, *shape)."""

    def __init__(self, shape: tuple[int, ...] = (), chunk: int = CHUNK):
        self.shape = tuple(shape)
        self._chunk = int(chunk)
        self._chunks: list[np.ndarray] = []
        self._count = 0

    def __len__(self) -> int:
        return self._count

    def append(self, row) -> None:
        if self._count == len(self._chunks) * self._chunk:
            self._chunks.append(np.empty((self._chunk, *self.shape)))
        self._chunks[-1][self._count % self._chunk] = row
        self._count += 1

    def row(self, k: int) -> np.ndarray:
        """Row k (negative: from the end), a view: writing into it changes the row."""
        if not -self._count <= k < self._count:
            raise IndexError(f"row {k} of {self._count}")
        k %= self._count
        return self._chunks[k // self._chunk][k % self._chunk]

    @property
    def nbytes(self) -> int:
        """The chunks' bytes: whole chunks, however few of their rows are used."""
        return sum(chunk.nbytes for chunk in self._chunks)

    def span(self, first: int, stop: int) -> np.ndarray:
        """Rows first..stop-1, (stop - first, *shape): a new array."""
        if not 0 <= first <= stop <= self._count:
            raise IndexError(f"rows {first}..{stop - 1} of {self._count}")
        c = self._chunk
        parts = [
            self._chunks[i][max(first - i * c, 0) : min(stop - i * c, c)] for i in range(first // c, -(-stop // c))
        ]
        return np.concatenate(parts) if parts else np.zeros((0, *self.shape))

    def array(self) -> np.ndarray:
        """Every row, (N, *shape): a new array."""
        if not self._chunks:
            return np.zeros((0, *self.shape))
        last = self._count - (len(self._chunks) - 1) * self._chunk
        return np.concatenate(self._chunks[:-1] + [self._chunks[-1][:last]])
