"""Giving freed heap memory back to the operating system between the stages of a run.

A stage that builds and drops many small objects (the I-state filter's shapely geometries
and memo over a day of stages) leaves glibc's heap fragmented: the memory is free for the
process but not returned, so the next stage (its recording, another tracker) allocates on top
of it and the run's peak resident size is the sum of the stages' peaks, not their maximum.
``malloc_trim(0)`` returns the free pages at the top and inside the heap's arenas (a day of a
home through ``istate``: 1.37 GB resident after the filter, 0.66 GB after the trim).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools


@functools.cache
def _malloc_trim():
    """glibc's ``malloc_trim``, or ``None`` where the C library has none (macOS, musl)."""
    name = ctypes.util.find_library("c")
    try:
        libc = ctypes.CDLL(name or "libc.so.6")
        trim = libc.malloc_trim
    except (OSError, AttributeError):
        return None
    trim.argtypes = [ctypes.c_size_t]
    trim.restype = ctypes.c_int
    return trim


def release_freed_memory() -> bool:
    """Return the heap's free pages to the operating system (``malloc_trim(0)``); ``False``
    where the C library cannot (nothing is done). Objects still alive are untouched."""
    trim = _malloc_trim()
    if trim is None:
        return False
    trim(0)
    return True
