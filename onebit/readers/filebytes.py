"""A log file's bytes in one ``bytes`` object, read into memory backed by huge pages.

``Path.read_bytes`` gives a large file a fresh buffer of 4 KiB pages: each page's first write
is a page fault of the kernel's (zeroing it), ~4 000 for a 16 MiB log -- a tenth of a reader
stage's CPU on 10^6 rows. numpy asks the kernel for transparent huge pages for its large arrays
(``madvise(MADV_HUGEPAGE)``, 2 MiB a fault); :func:`read_file` does the same for the bytes
object the readers parse: it makes the object uninitialised (``PyBytes_FromStringAndSize(NULL,
n)``, CPython's own way to fill a new ``bytes``), advises its buffer and reads the file into
it (~450 page faults for 16 MiB). Anywhere that cannot be done (another platform or Python, a
file that changed size while read, a small file) it is ``Path.read_bytes``: the same bytes.
"""

from __future__ import annotations

import ctypes
import os
import sys
from pathlib import Path

#: Files from this size on are read into advised memory (numpy's threshold for its arrays).
HUGE_READ_BYTES = 1 << 22
_HUGE_PAGE = 1 << 21
_MADV_HUGEPAGE = 14  # Linux


def _c_functions():
    """``(PyBytes_FromStringAndSize, PyBytes_AsString, madvise)`` through ctypes, or ``None``
    where they are not all there (not Linux, not CPython)."""
    if not sys.platform.startswith("linux") or sys.implementation.name != "cpython":
        return None
    try:
        api = ctypes.pythonapi
        make = api.PyBytes_FromStringAndSize
        make.restype, make.argtypes = ctypes.py_object, [ctypes.c_void_p, ctypes.c_ssize_t]
        buffer = api.PyBytes_AsString
        buffer.restype, buffer.argtypes = ctypes.c_void_p, [ctypes.py_object]
        madvise = ctypes.CDLL(None, use_errno=True).madvise
        madvise.restype, madvise.argtypes = ctypes.c_int, [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int]
    except (AttributeError, OSError):
        return None
    return make, buffer, madvise


_C = _c_functions()


def read_file(path: str | Path) -> bytes:
    """The bytes of ``path``, as ``Path(path).read_bytes()`` (whose errors it raises), a file of
    :data:`HUGE_READ_BYTES` or more read into a buffer advised for huge pages."""
    path = Path(path)
    if _C is None:
        return path.read_bytes()
    with open(path, "rb", buffering=0) as fh:
        n = os.fstat(fh.fileno()).st_size
        if n < HUGE_READ_BYTES:
            return fh.readall()
        make, buffer, madvise = _C
        data = make(None, n)  # uninitialised: filled below before anything else sees it
        start = buffer(data)
        lo, hi = -(-start // _HUGE_PAGE) * _HUGE_PAGE, (start + n) // _HUGE_PAGE * _HUGE_PAGE
        if hi > lo:
            madvise(lo, hi - lo, _MADV_HUGEPAGE)  # advice only: refused, the pages are small ones
        view = memoryview((ctypes.c_char * n).from_address(start)).cast("B")
        got = 0
        while got < n:
            k = fh.readinto(view[got:])
            if not k:
                break
            got += k
        if got == n and not fh.read(1):
            return data
    return path.read_bytes()  # the file changed size while read: read it again, plainly
