"""``onebit logs split DATASET OUT --every 1d``: a long dataset as one dataset folder per day.

A week or a month of a home's log is run as one dataset per day (or per any period) over
``onebit run-many`` -- the local pool or Ray -- with the same tables as ``onebit run`` on each
day's folder (tested). Each part ``OUT/part-NNN`` holds:

* every CSV log of the dataset (:data:`LOGS`) cut to the rows whose time falls in the part's
  window ``[start, start + every)``, each line as it was written (the header repeated);
* every other file of the dataset (``site.toml``, ``run.toml``, a residents profile, ...)
  copied as it is.

Times: a numeric ``t`` is seconds on the dataset's clock (the site's ``epoch`` when it has one);
a ``t`` written as a date and time is read as such. Windows start at multiples of ``every``
counted from midnight of the first day (``epoch``'s day, or the first stamp's), so ``--every
1d`` cuts at midnight. A line whose time cannot be read goes with the line before it (the
part's reader then rejects it with its reason, as the whole dataset's would): no line is
lost. A sensor on at midnight starts the next part with its ``OFF`` (the motion reader keeps
a first edge as the sensor's first state). ``OUT/split.toml`` lists every part's window.

Refused with a clear error: MCAP logs and ``camera.mp4`` (convert or cut them first: ``onebit
logs convert`` writes CSV), and an ``OUT`` that already has parts.
"""

from __future__ import annotations

import csv
import json
import math
import re
import shutil
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

import numpy as np

from onebit.core.errors import ConfigError, InputError
from onebit.core.writers import atomic_path, write_text

#: The CSV logs cut by time (every other file is copied whole).
LOGS = (
    "beams.csv",
    "crossings.csv",
    "truth.csv",
    "truth_crossings.csv",
    "truth_events.csv",
    "motion.csv",
    "proximity.csv",
    "frames.csv",
    "other.csv",
    "annotations.csv",
    "lost_offs.csv",
)
#: Files a split cannot cut.
REFUSED = (".mcap", ".mp4")

_UNITS = {"s": 1.0, "m": 60.0, "h": 3600.0, "d": 86400.0}


def parse_period(text: str) -> float:
    """``"1d"``, ``"6h"``, ``"90m"``, ``"3600"`` / ``"3600s"`` -> seconds (> 0).

    >>> parse_period("1d"), parse_period("6h"), parse_period("90")
    (86400.0, 21600.0, 90.0)
    """
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+)\s*([smhd]?)\s*", str(text))
    if not m or float(m.group(1)) <= 0:
        raise ConfigError(f"--every {text!r}: a period such as 1d, 6h, 90m or 3600 (seconds), > 0")
    return float(m.group(1)) * _UNITS[m.group(2) or "s"]


@dataclass(frozen=True)
class Part:
    """One part: its folder, window on the dataset's clock and rows written per log."""

    path: Path
    start: float
    end: float
    rows: dict[str, int]


def _epoch_offset(dataset: Path) -> float:
    """Seconds from midnight to the site's ``epoch`` (0 without one)."""
    site = dataset / "site.toml"
    if not site.exists():
        return 0.0
    import tomllib

    try:
        epoch = tomllib.loads(site.read_text(encoding="utf-8")).get("epoch")
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read site.toml: {exc}", file=site) from exc
    if not epoch:
        return 0.0
    e = datetime.fromisoformat(str(epoch))
    return e.hour * 3600.0 + e.minute * 60.0 + e.second + e.microsecond / 1e6


def _times(path: Path, lines: list[str]) -> np.ndarray:
    """The time of every data line (seconds; NaN where it cannot be read) of a CSV log whose
    header (``lines[0]``) has a ``t`` column; date-and-time stamps as seconds since midnight
    of their first day."""
    header = next(csv.reader([lines[0]]))
    if "t" not in [h.strip() for h in header]:
        raise InputError("no 't' column in the header: cannot split it by time", file=path, line=1)
    k = [h.strip() for h in header].index("t")
    raw = [row[k].strip() if len(row) > k else "" for row in csv.reader(lines[1:])]
    out = np.full(len(raw), np.nan)
    stamps: list[tuple[int, datetime]] = []
    for i, v in enumerate(raw):
        try:
            out[i] = float(v)
        except ValueError:
            try:
                stamps.append((i, datetime.fromisoformat(v)))
            except ValueError:
                pass
    if stamps:
        day0 = min(d for _, d in stamps).replace(hour=0, minute=0, second=0, microsecond=0)
        for i, d in stamps:
            out[i] = (d - day0).total_seconds()
    return out


def _carry(t: np.ndarray) -> np.ndarray:
    """``t`` with every NaN replaced by the time of the line before it (the first ones by the
    first readable time)."""
    ok = np.isfinite(t)
    if not ok.any():
        return np.zeros_like(t)
    idx = np.where(ok, np.arange(t.size), 0)
    np.maximum.accumulate(idx, out=idx)
    filled = t[idx]
    filled[: int(np.argmax(ok))] = t[ok][0]
    return filled


def split_dataset(dataset: Path, out: Path, *, every: float) -> list[Part]:
    """Cut ``dataset`` into parts of ``every`` seconds under ``out`` (module docstring)."""
    dataset, out = Path(dataset), Path(out)
    if not dataset.is_dir():
        raise InputError("not a dataset folder", file=dataset)
    if not math.isfinite(every) or every <= 0:
        raise ConfigError(f"every = {every!r}: a period in seconds > 0")
    files = sorted(p for p in dataset.iterdir() if p.is_file())
    refused = [p.name for p in files if p.suffix.lower() in REFUSED]
    if refused:
        raise InputError(
            f"cannot split {', '.join(refused)} by time: convert MCAP logs to CSV first (onebit logs convert), "
            "cut a video with a video tool",
            file=dataset,
        )
    logs = [p for p in files if p.name in LOGS]
    if not logs:
        raise InputError(f"no log to split (none of {', '.join(LOGS)})", file=dataset)
    if out.exists() and any(out.glob("part-*")):
        raise InputError("already has parts (part-*): remove them or choose another OUT", file=out)
    offset = _epoch_offset(dataset)
    cut: dict[str, tuple[str, list[str], np.ndarray]] = {}
    for p in logs:
        text = p.read_bytes().decode("latin-1")  # every byte kept as it is (written back the same way)
        lines = text.splitlines()
        if not lines:
            continue
        t = _carry(_times(p, lines))
        cut[p.name] = (lines[0], lines[1:], np.floor((t + offset) / every).astype(np.int64))
    ks = sorted({int(k) for _, _, w in cut.values() for k in np.unique(w)})
    if not ks:
        raise InputError("the logs have no rows", file=dataset)
    parts = []
    k0 = ks[0]
    for k in ks:
        folder = out / f"part-{k - k0:03d}"
        folder.mkdir(parents=True, exist_ok=False)
        for p in files:
            if p.name not in cut and p.name not in LOGS:
                shutil.copy2(p, folder / p.name)
        rows = {}
        for name, (header, body, w) in cut.items():
            mine = np.flatnonzero(w == k)
            rows[name] = int(mine.size)
            with atomic_path(folder / name) as tmp:
                tmp.write_bytes(("\n".join([header, *(body[i] for i in mine)]) + "\n").encode("latin-1"))
        parts.append(Part(folder, k * every - offset, (k + 1) * every - offset, rows))
    toml = "".join(
        f"[[parts]]\npath = {json.dumps(pt.path.name)}\nstart = {pt.start!r}\nend = {pt.end!r}\n"
        + "".join(f"rows.{n.removesuffix('.csv')} = {c}\n" for n, c in pt.rows.items())
        + "\n"
        for pt in parts
    )
    head = (
        f"# onebit logs split {dataset} --every {every} s\ndataset = {json.dumps(str(dataset))}\nevery = {every!r}\n\n"
    )
    write_text(head + toml, out / "split.toml")
    return parts
