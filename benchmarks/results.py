"""The results of ``python -m benchmarks`` as rows of one table, printed and written to
``benchmarks/results.csv`` so that commits can be compared.

A row is one measurement: what (the issue's row), the case and size, ours and the peer or
floor beside it (same process, same input), their ratio ``ours / peer`` (below 1: ours is
faster or smaller), the growth exponent of ours over the sizes of the row
(``log(ours_max / ours_min) / log(size_max / size_min)``: 1 = linear, 0 = flat), the goal
and whether it is met. Times are seconds unless the unit says otherwise.
"""

from __future__ import annotations

import csv
import math
import os
import re
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

RESULTS_CSV = Path(__file__).with_name("results.csv")
COLUMNS = (
    "row",
    "case",
    "size",
    "unit",
    "ours",
    "peer",
    "peer_name",
    "ratio",
    "growth",
    "goal",
    "met",
    "commit",
    "when",
)


@dataclass
class Result:
    row: str
    case: str
    size: float
    unit: str
    ours: float
    peer: float | None = None
    peer_name: str = ""
    growth: float | None = None
    goal: str = ""
    met: bool | None = None

    @property
    def ratio(self) -> float | None:
        if self.peer is None or not self.peer or not math.isfinite(self.peer):
            return None
        return self.ours / self.peer


@dataclass
class Table:
    """Collects :class:`Result` rows; :meth:`write` saves them (replacing earlier rows of the
    same ``row`` and ``case``, so one benchmark can be rerun alone)."""

    results: list[Result] = field(default_factory=list)

    def add(self, result: Result) -> Result:
        self.results.append(result)
        print(_line(result), flush=True)
        return result

    def write(self, path: Path = RESULTS_CSV) -> Path:
        commit, when = _commit(), time.strftime("%Y-%m-%dT%H:%M:%S")
        old = []
        if path.exists():
            with open(path, newline="") as fh:
                old = list(csv.DictReader(fh))
        mine = {(r.row, r.case, _num(r.size)) for r in self.results}
        keep = [o for o in old if (o.get("row"), o.get("case"), o.get("size")) not in mine]
        rows = keep + [
            {
                "row": r.row,
                "case": r.case,
                "size": _num(r.size),
                "unit": r.unit,
                "ours": _num(r.ours),
                "peer": _num(r.peer),
                "peer_name": r.peer_name,
                "ratio": _num(r.ratio),
                "growth": _num(r.growth),
                "goal": r.goal,
                "met": "" if r.met is None else str(bool(r.met)).lower(),
                "commit": commit,
                "when": when,
            }
            for r in self.results
        ]
        tmp = path.with_suffix(".csv.tmp")
        with open(tmp, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=COLUMNS, lineterminator="\n")
            w.writeheader()
            w.writerows(rows)
        os.replace(tmp, path)
        return path


HEADER = f"{'case':<34} {'size':>10} {'ours':>10} {'peer':>10} {'ours/peer':>9} {'growth':>6}  {'goal (met)'}"


def _line(r: Result) -> str:
    ratio = f"{r.ratio:.3g}" if r.ratio is not None else "-"
    peer = f"{r.peer:.4g}" if r.peer is not None else "-"
    growth = f"{r.growth:.2f}" if r.growth is not None else "-"
    met = "" if r.met is None else (" yes" if r.met else " NO")
    return f"{r.case:<34} {r.size:>10.4g} {r.ours:>10.4g} {peer:>10} {ratio:>9} {growth:>6}  {r.goal}{met}   [{r.unit}; peer: {r.peer_name or '-'}]"


def _num(v) -> str:
    if v is None:
        return ""
    if isinstance(v, float) and not math.isfinite(v):
        return ""
    return f"{v:.6g}"


def _commit() -> str:
    try:  # read-only: which commit the numbers belong to (plus "+dirty" for uncommitted work)
        root = Path(__file__).resolve().parent.parent
        head = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True, text=True, timeout=10
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=root,
            capture_output=True,
            text=True,
            timeout=10,
        ).stdout.strip()
        return head + ("+dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return ""


def growth(sizes, times) -> float | None:
    """``log(t_max / t_min) / log(n_max / n_min)`` between the smallest and largest size."""
    pairs = [(s, t) for s, t in zip(sizes, times) if t and t > 0]
    if len(pairs) < 2:
        return None
    (s0, t0), (s1, t1) = min(pairs), max(pairs)
    return math.log(t1 / t0) / math.log(s1 / s0) if s1 > s0 else None


def best(fn, repeat: int = 3, budget: float = 20.0, clock=time.perf_counter):
    """``(best time, last result)`` of up to ``repeat`` calls, stopping once ``budget`` s are spent."""
    out, b, spent = None, float("inf"), 0.0
    for _ in range(repeat):
        t0 = clock()
        out = fn()
        dt = clock() - t0
        b, spent = min(b, dt), spent + dt
        if spent > budget:
            break
    return b, out


_PEAK_HEAD = r"""
import re, sys
def kib(key):
    with open("/proc/self/status") as fh:
        return int(re.search(r"^" + key + r":\s+(\d+)", fh.read(), re.M).group(1))
"""
_PEAK_RESET = """
with open("/proc/self/clear_refs", "w") as fh:
    fh.write("5")  # reset the high-water mark VmHWM to the current RSS
before = kib("VmRSS")
"""
_PEAK_TAIL = """
print("PEAK_MB", (kib("VmHWM") - before) / 1024.0)
"""


def peak_mb(setup: str, call: str, timeout: float = 1800.0) -> float | None:
    """Peak resident-memory growth (MB) of ``call`` in a fresh interpreter after ``setup``
    (Linux: ``VmHWM`` reset through ``/proc/self/clear_refs``); ``None`` if unsupported."""
    try:
        out = subprocess.run(
            [sys.executable, "-c", _PEAK_HEAD + setup + "\n" + _PEAK_RESET + call + "\n" + _PEAK_TAIL],
            capture_output=True,
            text=True,
            check=True,
            timeout=timeout,
            cwd=Path(__file__).resolve().parent.parent,
        )
        m = re.search(r"PEAK_MB ([0-9.eE+-]+)", out.stdout)
        return float(m.group(1)) if m else None
    except (subprocess.SubprocessError, OSError, ValueError):
        return None
