"""docs/results.md is generated from docs/results/ and benchmarks/results.csv, and is current."""

from __future__ import annotations

import csv
import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _tool():
    spec = importlib.util.spec_from_file_location("results_md", ROOT / "tools" / "results_md.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["results_md"] = mod
    spec.loader.exec_module(mod)
    return mod


def test_results_md_is_current():
    tool = _tool()
    assert tool.main(["--check"]) == 0, "docs/results.md is stale: run python tools/results_md.py"


def test_every_measurement_row_is_on_the_page():
    tool = _tool()
    text = (ROOT / "docs" / "results.md").read_text()
    for path in sorted((ROOT / "docs" / "results").glob("*.csv")):
        with path.open(newline="") as fh:
            rows = list(csv.reader(fh))
        assert rows[1:], path
        for row in rows[1:]:
            assert tool._cell(row[0]) in text and tool._cell(row[-1]) in text, (path, row[0])
        assert f"docs/results/{path.name}" in text, f"{path.name} is not listed in docs/results/studies.toml"


def test_a_changed_number_makes_the_page_stale(tmp_path):
    tool = _tool()
    studies = tmp_path / "studies.toml"
    studies.write_text('[[study]]\nfile = "s.csv"\ntitle = "S"\n')
    (tmp_path / "s.csv").write_text("tracker,measure,paper,ours,command\nbeams,acc,-,0.87,onebit run D --out O\n")
    page = tool.render(studies, tmp_path / "none.csv")
    assert "| beams | acc | - | 0.87 | `onebit run D --out O` |" in page
    (tmp_path / "s.csv").write_text("tracker,measure,paper,ours,command\nbeams,acc,-,0.88,onebit run D --out O\n")
    assert tool.render(studies, tmp_path / "none.csv") != page


def test_a_ragged_row_names_the_file_and_line(tmp_path):
    tool = _tool()
    studies = tmp_path / "studies.toml"
    studies.write_text('[[study]]\nfile = "s.csv"\ntitle = "S"\n')
    (tmp_path / "s.csv").write_text("tracker,measure,paper,ours,command\nbeams,acc\n")
    with pytest.raises(SystemExit, match=r"s\.csv:2: 2 fields"):
        tool.render(studies, tmp_path / "none.csv")
