"""Heavy third-party modules imported on first use, so that a command that never needs them
(``onebit --help``, ``onebit simulate``, a reader) does not pay their import.

``rr = lazy_module("rerun")`` at the top of a module stands for ``import rerun as rr``: the
name is bound at once, the import runs at the first attribute looked up on it (``rr.log``),
and every later lookup is served from the real module. Only for third-party modules
(rerun, cv2, scipy.optimize, motmetrics); onebit's own modules are imported as usual.
"""

from __future__ import annotations

import contextlib
import gc
import importlib
import sys
import types
from collections.abc import Iterator


@contextlib.contextmanager
def collector_paused() -> Iterator[None]:
    """Python's cyclic garbage collector off inside the block, then as it was, and what the
    block made moved out of the collector's generations (``gc.freeze``). For importing a large
    library: its import makes some 10^5 objects that all stay (classes, functions, typing
    templates); the collections they trigger -- some over the whole heap -- find nothing to
    free, and would walk them again at every later full collection (Rerun: ~80 collections,
    0.02-0.05 s; numba's import and target set-up: 0.08-0.1 s of a 10^6-row beams run).
    Frozen objects are still freed by reference counting; only cycles among them stay."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        if enabled:
            gc.enable()


def quiet_import(name: str) -> types.ModuleType:
    """``importlib.import_module(name)`` with the collector paused (:func:`collector_paused`)."""
    if name in sys.modules:
        return sys.modules[name]
    with collector_paused():
        return importlib.import_module(name)


class LazyModule(types.ModuleType):
    """A stand-in for the module ``name`` that imports it on the first attribute looked up."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.__dict__["_lazy_name"] = name

    def __getattr__(self, attr: str):
        if attr.startswith("__") and attr.endswith("__") and attr not in ("__version__", "__file__", "__path__"):
            raise AttributeError(attr)  # introspection (copy, pickle, doctest) does not import
        module = quiet_import(self.__dict__["_lazy_name"])
        value = getattr(module, attr)
        self.__dict__[attr] = value
        return value

    def __repr__(self) -> str:
        return f"<lazy module {self.__dict__['_lazy_name']!r}>"


def lazy_module(name: str) -> types.ModuleType:
    """``name`` imported on first use (module docstring); the module itself if already imported."""
    return sys.modules.get(name) or LazyModule(name)
