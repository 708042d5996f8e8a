"""Start-up: ``import onebit`` loads no pipeline (PEP 562 lazy public names, onebit/__init__.py)
and importing kernel modules does not import numba (onebit.core.compiled)."""

from __future__ import annotations

import subprocess
import sys

import cv2
import numpy as np
import rerun as rr

from onebit.readers import camera
from onebit.viz.radii import ui_points


def _modules_after(code: str) -> set[str]:
    out = subprocess.run(
        [sys.executable, "-c", code + "\nimport sys\nprint(' '.join(sorted(sys.modules)))"],
        capture_output=True,
        text=True,
        check=True,
    )
    return set(out.stdout.split())


def test_import_onebit_loads_no_pipeline():
    mods = _modules_after("import onebit")
    assert not {m for m in mods if m.startswith("onebit.")}
    assert not mods & {"polars", "shapely", "scipy", "numba", "rerun", "cv2"}


def test_public_names_load_on_first_use():
    mods = _modules_after("import onebit\nonebit.load_site\nonebit.Site")
    assert "onebit.core.site" in mods and "onebit.pipeline.runner" not in mods


def test_kernel_modules_import_numba_only_when_a_kernel_runs():
    mods = _modules_after(
        "import onebit.readers.beams, onebit.models.graph_hmm.adaptive, onebit.trackers.beams.assignment"
    )
    assert "numba" not in mods
    mods = _modules_after(
        "import numpy as np\nfrom onebit.trackers.beams.assignment import assign_agents\nassign_agents(np.array([0]), np.array([1]), 2, compiled=True)"
    )
    assert "numba" in mods


#: Heavy third-party modules the CLI must not import before a command needs them.
HEAVY = {
    "rerun",
    "cv2",
    "networkx",
    "scipy.optimize",
    "scipy.sparse",
    "scipy.spatial",
    "numba",
    "motmetrics",
    "trackeval",
    "pandas",
    "matplotlib",
    "ray",
    "hypothesis",
}


def test_import_cli_imports_no_heavy_module():
    mods = _modules_after("import onebit.cli")
    assert "onebit.pipeline.runner" in mods  # the CLI did load the pipeline ...
    assert not mods & HEAVY, sorted(mods & HEAVY)  # ... and none of the heavy modules


def test_lazy_modules_import_on_first_use():
    mods = _modules_after("from onebit.core.lazy import lazy_module\nrr = lazy_module('rerun')")
    assert "rerun" not in mods
    mods = _modules_after("from onebit.core.lazy import lazy_module\nrr = lazy_module('rerun')\nrr.RecordingStream")
    assert "rerun" in mods


def test_ui_points_and_structuring_elements_match_their_libraries():
    for r in (0.75, 1.0, 1.5, 4.5, 9.0):
        assert ui_points(r) == rr.Radius.ui_points(r) and ui_points(r).dtype == np.float32
    assert np.array_equal(camera._OPEN, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3)))
    assert np.array_equal(camera._CLOSE, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5)))


def test_the_cli_process_ends_without_the_final_collection(tmp_path):
    """``main`` freezes the heap at exit (after the handlers registered later, Rerun's flush among
    them), so the interpreter's last collection does not walk it; a command still writes all it
    should. The handler registered before ``main`` runs after it and sees the frozen heap."""
    code = (
        "import atexit, gc, sys\n"
        "before = {}\n"
        "atexit.register(lambda: print('frozen more at exit:', gc.get_freeze_count() > before['n']))\n"
        "from onebit.cli import main\n"
        f"main(['simulate', 'beams-lab', {str(tmp_path / 'd')!r}, '--duration', '5', '--no-camera'])\n"
        f"main(['simulate', 'beams-lab', {str(tmp_path / 'e')!r}, '--duration', '5', '--no-camera'])\n"
        "garbage = [[i] for i in range(1000)]\n"  # tracked objects made after any import's freeze
        "before['n'] = gc.get_freeze_count()\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.splitlines()[-1] == "frozen more at exit: True"
    assert (tmp_path / "d" / "beams.csv").stat().st_size > 0 and (tmp_path / "e" / "site.toml").exists()
