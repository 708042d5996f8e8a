"""tools/sizes.py measures functions (def to last line, decorators out) and modules, and fails past the limits."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _tool():
    spec = importlib.util.spec_from_file_location("sizes_tool", ROOT / "tools" / "sizes.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["sizes_tool"] = mod
    spec.loader.exec_module(mod)
    return mod


def _function(name: str, body_lines: int, decorators: int = 0, indent: str = "") -> str:
    """A function of ``body_lines + 1`` lines (its ``def`` and its body) under ``decorators`` decorator lines."""
    deco = [f"{indent}@staticmethod" for _ in range(decorators)]
    body = [f"{indent}    x{i} = {i}" for i in range(body_lines)]
    return "\n".join([*deco, f"{indent}def {name}():", *body]) + "\n"


def _package(tmp_path: Path, files: dict[str, str]) -> Path:
    pkg = tmp_path / "pkg"
    for rel, text in files.items():
        (pkg / rel).parent.mkdir(parents=True, exist_ok=True)
        (pkg / rel).write_text(text)
    return pkg


def test_a_function_counts_from_def_to_its_last_line_without_decorators():
    tool = _tool()
    sizes = tool.function_sizes(_function("f", 9, decorators=3))
    assert [(s.name, s.line, s.lines) for s in sizes] == [("f", 4, 10)]


def test_methods_and_nested_functions_are_measured_with_qualified_names():
    tool = _tool()
    source = "class A:\n" + _function("m", 4, indent="    ") + "def outer():\n" + _function("inner", 2, indent="    ")
    sizes = {s.name: s.lines for s in tool.function_sizes(source)}
    assert sizes == {"A.m": 5, "outer": 4, "outer.inner": 3}


def test_module_lines_count_a_last_line_without_newline():
    tool = _tool()
    assert tool.module_lines("a = 1\nb = 2") == 2
    assert tool.module_lines("a = 1\nb = 2\n") == 2
    assert tool.module_lines("") == 0


def test_within_limits_exits_0(tmp_path, capsys):
    tool = _tool()
    pkg = _package(tmp_path, {"__init__.py": "", "a.py": _function("f", 119), "sub/b.py": _function("g", 80)})
    assert tool.main([str(pkg)]) == 0
    out = capsys.readouterr().out
    assert "all size limits hold" in out
    assert "pkg/sub/b.py" in out  # 81 lines: listed as long, within the count


def test_a_function_over_120_lines_fails_and_is_named(tmp_path, capsys):
    tool = _tool()
    pkg = _package(tmp_path, {"a.py": _function("short", 10) + _function("huge", 120, decorators=2)})
    assert tool.main([str(pkg)]) == 1
    out = capsys.readouterr().out
    assert "121  pkg/a.py:14  huge  (over 120)" in out
    assert "1 function(s) over 120 lines" in out


def test_sixteen_functions_over_80_lines_fail_fifteen_pass(tmp_path):
    tool = _tool()
    fifteen = _package(tmp_path / "ok", {f"m{i}.py": _function(f"f{i}", 81) for i in range(15)})
    sixteen = _package(tmp_path / "bad", {f"m{i}.py": _function(f"f{i}", 81) for i in range(16)})
    assert tool.main([str(fifteen)]) == 0
    assert tool.main([str(sixteen)]) == 1


def test_a_module_over_800_lines_fails(tmp_path, capsys):
    tool = _tool()
    ok = _package(tmp_path / "ok", {"a.py": "x = 1\n" * 800})
    bad = _package(tmp_path / "bad", {"a.py": "x = 1\n" * 801})
    assert tool.main([str(ok)]) == 0
    assert tool.main([str(bad)]) == 1
    assert "801  pkg/a.py" in capsys.readouterr().out


def test_report_mode_prints_the_offenders_and_exits_0(tmp_path, capsys):
    tool = _tool()
    pkg = _package(tmp_path, {"a.py": _function("huge", 200)})
    assert tool.main([str(pkg), "--report"]) == 0
    out = capsys.readouterr().out
    assert "huge  (over 120)" in out and "limits broken (reported only)" in out


def test_not_a_directory_is_a_usage_error(tmp_path, capsys):
    tool = _tool()
    assert tool.main([str(tmp_path / "missing")]) == 2
    assert "is not a directory" in capsys.readouterr().err
