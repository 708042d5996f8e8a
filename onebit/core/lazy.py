"""Heavy third-party modules imported on first use, so that a command that never needs them
(``onebit --help``, ``onebit simulate``, a reader) does not pay their import.

``rr = lazy_module("rerun")`` at the top of a module stands for ``import rerun as rr``: the
name is bound at once, the import runs at the first attribute looked up on it (``rr.log``),
and every later lookup is served from the real module. Only for third-party modules
(rerun, cv2, scipy.optimize, motmetrics); onebit's own modules are imported as usual.
"""

from __future__ import annotations

import importlib
import sys
import types


class LazyModule(types.ModuleType):
    """A stand-in for the module ``name`` that imports it on the first attribute looked up."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.__dict__["_lazy_name"] = name

    def __getattr__(self, attr: str):
        if attr.startswith("__") and attr.endswith("__") and attr not in ("__version__", "__file__", "__path__"):
            raise AttributeError(attr)  # introspection (copy, pickle, doctest) does not import
        module = importlib.import_module(self.__dict__["_lazy_name"])
        value = getattr(module, attr)
        self.__dict__[attr] = value
        return value

    def __repr__(self) -> str:
        return f"<lazy module {self.__dict__['_lazy_name']!r}>"


def lazy_module(name: str) -> types.ModuleType:
    """``name`` imported on first use (module docstring); the module itself if already imported."""
    return sys.modules.get(name) or LazyModule(name)
