"""Heavy imports with the collector paused: no collection inside, the collector as it was
after, the imported objects frozen out of later full collections."""

from __future__ import annotations

import gc
import subprocess
import sys

from onebit.core.lazy import collector_paused, quiet_import


def test_collector_paused_restores_the_collector_and_freezes_what_the_block_made():
    was = gc.isenabled()
    before = gc.get_freeze_count()
    try:
        gc.enable()
        with collector_paused():
            assert not gc.isenabled()
            made = [[i] for i in range(1000)]  # tracked containers
        assert gc.isenabled()
        assert gc.get_freeze_count() >= before + len(made)
        gc.disable()
        with collector_paused():
            pass
        assert not gc.isenabled()  # off stays off
    finally:
        gc.unfreeze()
        (gc.enable if was else gc.disable)()


def test_quiet_import_returns_the_module_once_imported():
    assert quiet_import("json") is sys.modules["json"]


def _no_collection_during(snippet: str) -> None:
    code = f"""
import gc, sys
inside = {{"on": False}}
starts = []
gc.callbacks.append(lambda phase, info: starts.append(info) if phase == "start" and inside["on"] else None)
{snippet}
assert gc.isenabled()
assert not starts, starts
print("ok")
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-2000:]


def test_the_first_kernel_sets_numba_up_without_a_collection():
    """The process's first compiled kernel imports numba and sets its target up (some 10^5
    objects that stay): without the pause, full collections ran inside it."""
    _no_collection_during(
        """
import numpy as np
from onebit.core import compiled
from onebit.readers import kernels
assert not compiled.numba_loaded()
inside["on"] = True
kernels.beam_passes(np.zeros(3, np.int64), np.zeros(3, np.int8), np.array([True, False, True]), 1)
inside["on"] = False
assert compiled.numba_loaded()
"""
    )
