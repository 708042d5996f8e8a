"""The package as a whole: the public API (``onebit.run``, ``onebit.load_site``) and the
layering rule that import-linter cannot see (no function-level imports of onebit modules:
an import hidden in a function would dodge the layers contract)."""

from __future__ import annotations

import ast
from pathlib import Path

import polars as pl
import pytest

import onebit
from onebit.core.errors import SiteError
from onebit.datasets.beams_sim import write_beams_dataset

PACKAGE = Path(onebit.__file__).parent


def _function_level_onebit_imports(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for sub in ast.walk(node):
                if isinstance(sub, ast.ImportFrom) and (sub.module or "").startswith("onebit"):
                    found.append(f"{path.relative_to(PACKAGE.parent)}:{sub.lineno}: from {sub.module}")
                if isinstance(sub, ast.Import) and any(a.name.startswith("onebit") for a in sub.names):
                    found.append(f"{path.relative_to(PACKAGE.parent)}:{sub.lineno}: import onebit...")
    return found


def test_no_function_level_imports_of_onebit():
    found = [f for p in sorted(PACKAGE.rglob("*.py")) for f in _function_level_onebit_imports(p)]
    assert found == [], "\n".join(found)


def _dynamic_rerun_imports(path: Path) -> list[str]:
    """Calls that import rerun by name at run time (``lazy_module("rerun")``,
    ``importlib.import_module("rerun.blueprint")``, ``__import__("rerun")``): import-linter
    sees only import statements, so "only viz imports rerun" needs this too."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant):
            name = node.func.attr if isinstance(node.func, ast.Attribute) else getattr(node.func, "id", "")
            arg = node.args[0].value
            if (
                name in {"lazy_module", "import_module", "__import__"}
                and isinstance(arg, str)
                and arg.split(".")[0] == "rerun"
            ):
                found.append(f"{path}:{node.lineno}: {name}({arg!r})")
    return found


def test_only_viz_imports_rerun_lazily_too(tmp_path):
    outside = [p for p in sorted(PACKAGE.rglob("*.py")) if "viz" not in p.relative_to(PACKAGE).parts[:1]]
    found = [f for p in outside for f in _dynamic_rerun_imports(p)]
    assert found == [], "\n".join(found)
    assert any(_dynamic_rerun_imports(p) for p in (PACKAGE / "viz").rglob("*.py"))  # the check sees what viz does
    bad = tmp_path / "bad.py"
    bad.write_text('from onebit.core.lazy import lazy_module\nrr = lazy_module("rerun")\n')
    assert len(_dynamic_rerun_imports(bad)) == 1


def test_public_api_runs_a_dataset(tmp_path):
    data = write_beams_dataset(tmp_path / "d", "beams-lab", seed=3, duration=40.0, camera=False)
    site = onebit.load_site(data / "site.toml")
    assert isinstance(site, onebit.Site) and site.beams
    res = onebit.run(data, tmp_path / "out", trackers=["beams"], config={"beams": {"policy": "lifo"}})
    assert res.ok and res.status["beams"].startswith("ok")
    assert isinstance(res.report, pl.DataFrame) and res.report.height > 0
    assert (tmp_path / "out" / "tables" / "beams_tracks.parquet").exists()
    assert 'policy = "lifo"' in (tmp_path / "out" / "run.toml").read_text()
    # a run.toml path works as config too
    (tmp_path / "run.toml").write_text('[beams]\npolicy = "fifo"\n')
    res2 = onebit.run(data, tmp_path / "out2", trackers=["beams"], config=tmp_path / "run.toml")
    assert 'policy = "fifo"' in (tmp_path / "out2" / "run.toml").read_text() and res2.ok


def test_load_site_names_the_file(tmp_path):
    (tmp_path / "site.toml").write_text("units = 'm'\n")
    with pytest.raises(SiteError, match="boundary"):
        onebit.load_site(tmp_path / "site.toml")
