"""Compiled kernels, compiled when first needed: ``@kernel`` marks a plain Python function as a
numba kernel (``numba.njit(cache=True, nogil=True)``).

Importing a module of kernels costs nothing: numba is imported, and the module's kernels are
turned into numba dispatchers, on the first call of any of them (each one is compiled for
its argument types on its own first call, or loaded from numba's on-disk cache, ``cache=True``,
which makes later processes start in milliseconds). So a command that never runs a kernel --
``onebit --help``, ``onebit simulate``, a reader of a file without beams -- does not pay
numba's import. When a module's kernels become dispatchers the module's names are rebound to
them (a kernel imported from another module too: that module is turned as well, so the
kernels the imported one calls are dispatchers in its own module), so a kernel that calls
another compiles against the callee's dispatcher, and callers that look the kernel up on the
module reach numba directly.

The undecorated function stays available as ``.py_func`` (numba's name for it).
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable
from typing import Any

from onebit.core.lazy import collector_paused, quiet_import

#: Options of every kernel: cached on disk, and free of the GIL while it runs.
OPTIONS = {"cache": True, "nogil": True}


class Kernel:
    """A function to compile with numba on first use (see the module docstring)."""

    def __init__(self, fn: Callable[..., Any]) -> None:
        self.py_func = fn
        self._dispatcher = None
        functools.update_wrapper(self, fn)

    @property
    def dispatcher(self):
        """The numba dispatcher (importing numba and rebinding the module's kernels once)."""
        if self._dispatcher is None:
            _compile_module(self.py_func.__module__)
        if self._dispatcher is None:  # not (or no longer) bound in its module
            import numba

            self._dispatcher = numba.njit(**OPTIONS)(self.py_func)
        return self._dispatcher

    def __call__(self, *args: Any) -> Any:
        if not _STATE["loaded"]:  # the process's first kernel: numba's import and target set-up
            with collector_paused():  # ~10^5 objects that stay: collections would find nothing
                return self.dispatcher(*args)
        return self.dispatcher(*args)


def numba_loaded() -> bool:
    """Whether a kernel module has been turned into numba dispatchers in this process (numba
    imported and its compiler set up): then one more kernel costs milliseconds to load, not
    the 0.3-0.5 s of the first. A caller with a vectorised numpy path beside a kernel uses it
    while this is false."""
    return _STATE["loaded"]


_STATE = {"loaded": False}


def kernel(fn: Callable[..., Any]) -> Kernel:
    """Mark ``fn`` (a module-level function in numba's nopython subset) as a compiled kernel."""
    return Kernel(fn)


def _compile_module(name: str) -> None:
    numba = quiet_import("numba")  # deferred: a process that runs no kernel never imports it

    _STATE["loaded"] = True
    module = sys.modules[name]
    for attr, value in list(vars(module).items()):  # its own kernels first
        if isinstance(value, Kernel) and value.py_func.__module__ == name:
            if value._dispatcher is None:
                value._dispatcher = numba.njit(**OPTIONS)(value.py_func)
            setattr(module, attr, value._dispatcher)
    for attr, value in list(vars(module).items()):  # then those it imports: their module's turn
        if isinstance(value, Kernel):
            setattr(module, attr, value.dispatcher)
