"""Measure the functions and modules of the ``onebit/`` package and hold them to their limits.

A function's size is its lines from ``def`` to its last line (decorators excluded; a nested
function or a method is measured on its own too, and also counts inside its parent); a
module's size is its number of lines. The limits (issue #35):

- no function over 120 lines;
- at most 15 functions over 80 lines;
- no module over 800 lines.

    python tools/sizes.py              # print the offenders; exit 1 when a limit is broken
    python tools/sizes.py --report     # print the same, always exit 0
    python tools/sizes.py PATH         # measure another package directory (tests use this)

Only the standard library: it runs before anything is installed.
"""

from __future__ import annotations

import argparse
import ast
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "onebit"
#: no function may be longer than this (lines)
FUNCTION_MAX = 120
#: a function longer than this is "long" ...
FUNCTION_LONG = 80
#: ... and at most this many may be
LONG_FUNCTIONS_MAX = 15
#: no module may be longer than this (lines)
MODULE_MAX = 800


@dataclass(frozen=True)
class Size:
    """One measured function or module: where it is, its name and its number of lines."""

    path: str
    line: int
    name: str
    lines: int


def module_lines(source: str) -> int:
    """The number of lines of a module's source (a last line without newline counts)."""
    return len(source.splitlines())


def function_sizes(source: str, path: str = "<string>") -> list[Size]:
    """Every function and method of ``source``, nested ones included, with its qualified name."""
    tree = ast.parse(source, filename=path)
    found: list[Size] = []

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                name = f"{prefix}{child.name}"
                found.append(Size(path, child.lineno, name, child.end_lineno - child.lineno + 1))
                visit(child, f"{name}.")
            elif isinstance(child, ast.ClassDef):
                visit(child, f"{prefix}{child.name}.")
            else:
                visit(child, prefix)

    visit(tree, "")
    return found


def measure(package: Path) -> tuple[list[Size], list[Size]]:
    """``(functions, modules)`` of every ``*.py`` under ``package``, paths relative to its parent."""
    functions: list[Size] = []
    modules: list[Size] = []
    for file in sorted(package.rglob("*.py")):
        rel = file.relative_to(package.parent).as_posix()
        source = file.read_text(encoding="utf-8")
        modules.append(Size(rel, 1, rel, module_lines(source)))
        functions.extend(function_sizes(source, rel))
    return functions, modules


def check(functions: list[Size], modules: list[Size]) -> tuple[list[str], list[str]]:
    """``(report lines, broken limits)``: the offenders, longest first, and one line per broken limit."""
    long_functions = sorted((f for f in functions if f.lines > FUNCTION_LONG), key=lambda f: (-f.lines, f.path))
    too_long = [f for f in long_functions if f.lines > FUNCTION_MAX]
    big_modules = sorted((m for m in modules if m.lines > MODULE_MAX), key=lambda m: (-m.lines, m.path))
    report = [f"functions over {FUNCTION_LONG} lines: {len(long_functions)} (at most {LONG_FUNCTIONS_MAX})"]
    report += [
        f"  {f.lines:5d}  {f.path}:{f.line}  {f.name}{'  (over ' + str(FUNCTION_MAX) + ')' if f.lines > FUNCTION_MAX else ''}"
        for f in long_functions
    ]
    report.append(f"modules over {MODULE_MAX} lines: {len(big_modules)}")
    report += [f"  {m.lines:5d}  {m.path}" for m in big_modules]
    broken = []
    if too_long:
        broken.append(f"{len(too_long)} function(s) over {FUNCTION_MAX} lines")
    if len(long_functions) > LONG_FUNCTIONS_MAX:
        broken.append(f"{len(long_functions)} functions over {FUNCTION_LONG} lines (at most {LONG_FUNCTIONS_MAX})")
    if big_modules:
        broken.append(f"{len(big_modules)} module(s) over {MODULE_MAX} lines")
    return report, broken


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("package", nargs="?", type=Path, default=PACKAGE, help="package directory (default: onebit/)")
    parser.add_argument("--report", action="store_true", help="print the offenders and exit 0 whatever they are")
    args = parser.parse_args(argv)
    if not args.package.is_dir():
        print(f"sizes.py: {args.package} is not a directory", file=sys.stderr)
        return 2
    report, broken = check(*measure(args.package.resolve()))
    print("\n".join(report))
    if broken:
        print(("limits broken (reported only): " if args.report else "limits broken: ") + "; ".join(broken))
        return 0 if args.report else 1
    print("all size limits hold")
    return 0


if __name__ == "__main__":
    sys.exit(main())
