"""docs/parameters.md is generated from the config declarations, and is current."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

from onebit.core.params import describe
from onebit.pipeline.config_show import config_sections

ROOT = Path(__file__).resolve().parents[2]


def _tool():
    spec = importlib.util.spec_from_file_location("params_md", ROOT / "tools" / "params_md.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["params_md"] = mod
    spec.loader.exec_module(mod)
    return mod


def test_parameters_md_is_current():
    assert _tool().main(["--check"]) == 0, "docs/parameters.md is stale: run python tools/params_md.py"


def test_every_parameter_is_on_the_page_and_the_page_is_linked():
    text = (ROOT / "docs" / "parameters.md").read_text()
    for name, cls in config_sections().items():
        assert f"## `[{name}]`" in text
        for p in describe(cls):
            assert f"| `{p.name}` |" in text, (name, p.name)
    assert "parameters.md" in (ROOT / "mkdocs.yml").read_text()
    assert "docs/parameters.md" in (ROOT / "README.md").read_text()


def test_a_stale_page_is_reported(tmp_path):
    stale = tmp_path / "parameters.md"
    stale.write_text("old\n")
    assert _tool().main(["--check", "--out", str(stale)]) == 1
