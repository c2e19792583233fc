"""Whitespace tables (TUM trajectories, image lists) read in one C pass when they are plain.

Parsed line by line in Python, a 21,000-line file makes some 200,000 small objects at once; the
few long-lived ones made beside them (the reader's arrays) then pin the heap's arenas, so the
reader holds several times its numbers and names. `np.loadtxt` makes no object per line.
It is taken only for text whose lines and fields it splits exactly as Python's `splitlines` and
`split` do; anything else (a comma, a comment after the data, a stray field, a word where a number
goes, a Unicode space) returns None, and the caller's own line-by-line parser reads the file and
names the line that is wrong.
"""

from __future__ import annotations

import io
import re
import warnings

import numpy as np

# Line breaks other than "\n" (splitlines splits on them), whitespace other than space and tab
# (str.split splits on it), or a "#" after data on a line (loadtxt would cut it as a comment).
_NOT_PLAIN = re.compile(r"[\r\x0b\x0c\x1c-\x1e\x85\u2028\u2029]|[^\S \t\n]|^[ \t]*[^#\s][^\n]*#", re.MULTILINE)


def plain_table(text: str, width: int, dtype: type = np.float64) -> np.ndarray | None:
    """The (rows, width) table of `text` ("#" lines and blank lines skipped), or None when the
    text is not plain (see above) or holds no row."""
    if _NOT_PLAIN.search(text):
        return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # "input contained no data", comment lines in chunks
            table = np.loadtxt(io.StringIO(text), dtype=dtype, comments="#", ndmin=2)
    except ValueError:
        return None
    if table.shape[0] == 0 or table.shape[1] != width:
        return None
    return table
