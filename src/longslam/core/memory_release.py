"""Give the C heap's free memory back to the operating system.

A big solve (GTSAM's factor graphs and Python's objects for every frame of a kilometre) frees
tens of megabytes in small blocks that glibc keeps for reuse: the process's resident memory
stays at the solve's peak while the next step touches fresh pages of its own. Trimming the heap
once such a phase is over lets the next one start from what is really in use.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import gc
import sys

M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3  # glibc's mallopt parameters (malloc.h)
LARGE_BLOCK = 1 << 20  # bytes: blocks this large or larger get pages of their own
# Bytes of free memory at the heap's top kept for the next allocations rather than returned.
# Fixing the mmap threshold also fixes this one (glibc then adjusts neither) at its 128 KiB
# default, so the heap's top went back to the system after nearly every frame's arrays and was
# faulted in again by the next frame's: page faults at every step. Above it, a step's own arrays
# (the ones under LARGE_BLOCK) reuse the pages the step before freed; `release_free_memory`
# still returns everything free at the end of a phase.
TRIM_THRESHOLD = 16 << 20


@functools.cache
def _libc():
    """The C library, looked up once (finding it runs `ldconfig`); None off Linux."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        return ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
    except OSError:
        return None


def map_large_blocks(threshold: int = LARGE_BLOCK, trim: int = TRIM_THRESHOLD) -> bool:
    """Give every allocation of `threshold` bytes or more pages of its own (glibc's mallopt
    M_MMAP_THRESHOLD), returned to the system when it is freed, and keep up to `trim` bytes free
    at the heap's top (M_TRIM_THRESHOLD, see TRIM_THRESHOLD); True if set.

    By default glibc raises that threshold each time such a block is freed (up to 32 MiB), and
    from then on serves blocks of that size from the heap, which keeps their pages after they
    are freed: a long run's resident memory then creeps up with every large array it ever held.
    Fixing the threshold stops that."""
    mallopt = getattr(_libc(), "mallopt", None)
    if mallopt is None:
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    return bool(mallopt(M_MMAP_THRESHOLD, int(threshold))) and bool(mallopt(M_TRIM_THRESHOLD, int(trim)))


@functools.cache
def _malloc_trim():
    """glibc's malloc_trim; None elsewhere (musl or another C library without it)."""
    trim = getattr(_libc(), "malloc_trim", None)
    if trim is not None:
        trim.argtypes = [ctypes.c_size_t]
    return trim


def release_free_memory(collect: bool = True) -> None:
    """Return the heap's free pages to the system (glibc's malloc_trim), after collecting garbage
    unless `collect` is False; a no-op without glibc."""
    if collect:
        gc.collect()
    trim = _malloc_trim()
    if trim is not None:
        trim(0)
