"""Start-up: ``import onebit`` loads no pipeline (PEP 562 lazy public names, onebit/__init__.py)
and importing kernel modules does not import numba (onebit.core.compiled)."""

from __future__ import annotations

import subprocess
import sys


def _modules_after(code: str) -> set[str]:
    out = subprocess.run(
        [sys.executable, "-c", code + "\nimport sys\nprint(' '.join(sorted(sys.modules)))"],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    return set(out.stdout.split())


def test_import_onebit_loads_no_pipeline():
    mods = _modules_after("import onebit")
    assert not {m for m in mods if m.startswith("onebit.")}
    assert not mods & {"polars", "shapely", "scipy", "numba", "rerun", "cv2"}


def test_public_names_load_on_first_use():
    mods = _modules_after("import onebit\nonebit.load_site\nonebit.Site")
    assert "onebit.core.site" in mods and "onebit.pipeline.runner" not in mods


def test_kernel_modules_import_numba_only_when_a_kernel_runs():
    mods = _modules_after("import onebit.readers.beams, onebit.models.graph_hmm.adaptive, onebit.trackers.beams.assignment")
    assert "numba" not in mods
    mods = _modules_after("import numpy as np\nfrom onebit.trackers.beams.assignment import assign_agents\nassign_agents(np.array([0]), np.array([1]), 2, compiled=True)")
    assert "numba" in mods
