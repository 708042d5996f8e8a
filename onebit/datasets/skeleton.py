"""``onebit init DATASET --from LOG [LOG...]``: a commented ``site.toml`` skeleton from logs.

The sensor ids are read from the logs, each sensor's kind is guessed and every guess is
marked ``# CHECK: guessed from ...`` for the user to confirm. What the logs cannot say is
written as a placeholder marked the same way: positions (a grid), the boundary (the grid's
box), the sensor graph (left commented out: a graph of placeholder positions would mislead a
tracker) and the number of people (``targets``).

Logs understood (:func:`log_format` tells them apart from their first lines):

``casas``
    a CASAS event log, ``date time sensor value [...]`` (:mod:`onebit.readers.casas`); kinds
    from the CASAS ids (``M###`` motion, ``D###`` contact, ``T###`` temperature, ...) or the
    values a named sensor takes.
``toggles``
    a toggle CSV ``t,sensor,value`` (``motion.csv``); a sensor held on for long is guessed a
    level (presence) sensor, one with short ons an edge (PIR trigger).
``frames-wide`` / ``frames-list``
    a frame log ``t,1,2,3,...`` or ``t,active`` (docs/frame-logs.md): level sensors.
``per-second``
    an ARAS-style day file: one row per second, space separated, N sensor columns of 0/1
    then 2 activity columns (one per resident). Columns are named by position (``1`` ...
    ``N``) unless a README beside the file lists them (``Column 3: Fo1 Force sensor Bed``, or
    ids such as ``Ph1``, ``Ir2``, ``Fo1`` listed once each, N of them in order); the words of
    a README line guess the kind.
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

import polars as pl

from onebit.core.errors import InputError
from onebit.core.site import site_from_dict
from onebit.core.writers import write_text
from onebit.readers.casas import DATETIME_RE, read_casas

#: How a guessed kind is declared: (site.toml table, signal, ignore, what it means).
KINDS = {
    "motion": ("motion_sensors", "edge", False, "a PIR: an on is motion beginning in its field"),
    "presence": ("binary_sensors", "level", False, "on while someone is in its footprint"),
    "contact": ("binary_sensors", "edge", False, "a door or cupboard contact: an open is an event there"),
    "environment": ("binary_sensors", "level", True, "not about people (temperature, light, ...): ignored"),
}

#: Words of a README line or CASAS kinds -> a kind of :data:`KINDS`.
_WORDS = (
    (r"temp|light|lux|photo|humid|co2|power|energy|analog|clock", "environment"),
    (r"contact|door|reed|cupboard|drawer|fridge|magnet", "contact"),
    (r"pir|motion|movement", "motion"),
    (r"\bir\b|infra|force|pressure|mat|distance|sonar|seat|bed|couch|proximity|presence|occupan", "presence"),
)
_ID_PREFIX = {"ph": "environment", "te": "environment", "co": "contact", "ir": "presence", "fo": "presence",
              "di": "presence", "so": "presence", "pr": "presence", "m": "motion", "d": "contact", "t": "environment",
              "l": "environment"}  # fmt: skip
_CASAS_KINDS = {"motion": "motion", "contact": "contact", "door": "contact", "item": "contact"}
GRID_SPACING = 2.0  #: metres between placeholder positions
RADIUS = 1.0  #: placeholder footprint radius (m)
HELD_S = 10.0  #: a toggle sensor whose median on lasts longer is guessed a level sensor


@dataclass(frozen=True)
class SensorGuess:
    """One sensor found in a log: its id, guessed kind (:data:`KINDS`) and why."""

    id: str
    kind: str
    why: str


def log_format(path: Path) -> str:
    """The format of a log (module docstring), from its first non-blank lines; an
    :class:`InputError` naming the file and line when none fits."""
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            head = [(i, ln.strip()) for i, ln in zip(range(1, 200), fh) if ln.strip() and not ln.startswith("#")]
    except OSError as exc:
        raise InputError(f"cannot read the log: {exc.strerror}", file=str(path)) from None
    if not head:
        raise InputError("the log is empty", file=str(path))
    line_no, first = head[0]
    if "," in first:
        cols = [c.strip().strip('"').lower() for c in first.split(",")]
        if {"t", "sensor", "value"} <= set(cols):
            return "toggles"
        if cols[0] == "t" and cols[1:] == ["active"]:
            return "frames-list"
        if cols[0] == "t" and len(cols) > 1:
            return "frames-wide"
    if re.match(DATETIME_RE, first) and len(first.split()) >= 3:
        return "casas"
    rows = [ln.split() for _, ln in head[:20]]
    if all(len(r) == len(rows[0]) >= 3 and all(re.fullmatch(r"-?\d+", x) for x in r) for r in rows):
        return "per-second"
    raise InputError(
        "not a log onebit init knows: expected a CASAS log (date time sensor value), a toggle CSV "
        "(t,sensor,value), a frame log (t,1,2,... or t,active) or a per-second file (rows of 0/1 "
        f"sensor columns then 2 activity columns); the line starts {first[:60]!r}",
        file=str(path),
        line=line_no,
    )


def kind_from_id(sid: str) -> str | None:
    """A kind guessed from an id's letters (``Ph1`` photocell, ``Ir2`` IR, ``M003`` motion), else ``None``."""
    m = re.fullmatch(r"([a-z]+)\d+", sid.lower())
    return _ID_PREFIX.get(m.group(1)) if m else None


def kind_from_words(text: str) -> str | None:
    """A kind guessed from words (a README's description, a sensor's name), else ``None``."""
    low = text.lower()
    for rx, kind in _WORDS:
        if re.search(rx, low):
            return kind
    return None


def guess_sensors(path: str | Path) -> tuple[str, list[SensorGuess]]:
    """``(format, sensors)`` of one log (:func:`log_format`), sensors in the log's order."""
    path = Path(path)
    fmt = log_format(path)
    if fmt == "casas":
        return fmt, _casas(path)
    if fmt == "toggles":
        return fmt, _toggles(path)
    if fmt == "frames-wide":
        ids = pl.read_csv(path, n_rows=0, comment_prefix="#").columns[1:]
        return fmt, [SensorGuess(i, "presence", "a column of a frame log (levels every frame)") for i in ids]
    if fmt == "frames-list":
        act = pl.read_csv(path, schema_overrides={"active": pl.String}, comment_prefix="#")["active"].drop_nulls()
        ids = sorted({x for a in act.to_list() for x in re.split(r"[ ;|]+", a.strip()) if x}, key=_natural)
        return fmt, [SensorGuess(i, "presence", "listed active in a frame log (levels every frame)") for i in ids]
    return fmt, _per_second(path)


def _casas(path: Path) -> list[SensorGuess]:
    ev = read_casas(path).events
    kinds = ev.group_by("sensor", maintain_order=True).agg(pl.col("kind").first())
    out = []
    for sid, kind in kinds.iter_rows():
        k = _CASAS_KINDS.get(kind, "environment")
        out.append(SensorGuess(sid, k, f"CASAS kind '{kind}' (from the id or its values)"))
    return out


def _toggles(path: Path) -> list[SensorGuess]:
    df = pl.read_csv(path, schema_overrides={"sensor": pl.String, "value": pl.String}, comment_prefix="#")
    on = pl.col("value").str.strip_chars().str.to_lowercase().is_in(["1", "on", "true", "open", "present"])
    df = df.with_columns(pl.col("t").cast(pl.Float64, strict=False), on=on).drop_nulls(["t", "sensor"]).sort("t")
    held = (
        df.with_columns(next_t=pl.col("t").shift(-1).over("sensor"), next_on=pl.col("on").shift(-1).over("sensor"))
        .filter(pl.col("on") & ~pl.col("next_on").fill_null(True))
        .group_by("sensor")
        .agg((pl.col("next_t") - pl.col("t")).median().alias("on_s"))
    )
    on_s = dict(held.iter_rows())
    out = []
    for sid in df["sensor"].unique(maintain_order=True).to_list():
        s = on_s.get(sid)
        by_name = kind_from_words(sid) or kind_from_id(sid)
        if by_name == "environment":
            out.append(SensorGuess(sid, "environment", f"its id {sid!r} reads like a non-person sensor"))
        elif s is not None and s > HELD_S:
            out.append(SensorGuess(sid, "presence", f"toggle log: median on {s:.0f} s (held on: a level)"))
        else:
            what = "no on-off pair" if s is None else f"median on {s:.1f} s"
            out.append(SensorGuess(sid, "motion", f"toggle log: {what} (short ons: a PIR's trigger)"))
    return out


def _per_second(path: Path) -> list[SensorGuess]:
    with open(path, encoding="utf-8", errors="replace") as fh:
        first = next(ln for ln in fh if ln.strip())
    n = len(first.split()) - 2
    if n < 1:
        raise InputError("a per-second file needs sensor columns before its 2 activity columns", file=str(path), line=1)
    named = readme_names(path.parent, n)
    if named is None:
        return [
            SensorGuess(str(i), "presence", f"column {i} of a per-second file (no README naming it)")
            for i in range(1, n + 1)
        ]
    out = []
    for i, (sid, words) in enumerate(named, start=1):
        kind = kind_from_id(sid) or kind_from_words(words) or "presence"
        out.append(SensorGuess(sid, kind, f"column {i}, README: {words.strip()[:60]!r}"))
    return out


def readme_names(folder: Path, n: int) -> list[tuple[str, str]] | None:
    """``[(id, words), ...]`` of the ``n`` sensor columns from a README in ``folder``: lines
    numbered ``1``..``n`` (``Column 3: Fo1 Force sensor``, ``3) Fo1 ...``), else ``n`` lines
    each starting with a distinct id of letters then digits (``Ph1 Photocell Wardrobe``), in
    order; ``None`` when no README there lists them."""
    for p in sorted(folder.iterdir()):
        if not p.is_file() or not p.name.lower().startswith("readme"):
            continue
        lines = p.read_text(encoding="utf-8", errors="replace").splitlines()
        numbered: dict[int, tuple[str, str]] = {}
        for ln in lines:
            m = re.match(r"^\s*(?:col(?:umn)?\.?\s*)?(\d{1,3})\s*[:.)\-\t ]\s*([A-Za-z][\w-]*)(.*)$", ln, re.I)
            if m and 1 <= int(m.group(1)) <= n and int(m.group(1)) not in numbered:
                numbered[int(m.group(1))] = (m.group(2), m.group(2) + " " + m.group(3))
        if len(numbered) == n:
            return [numbered[i] for i in range(1, n + 1)]
        ids: list[tuple[str, str]] = []
        for ln in lines:
            m = re.match(r"^\s*([A-Z][a-z]{0,2}\d{1,2})\b(.*)$", ln)
            if m and m.group(1) not in {i for i, _ in ids}:
                ids.append((m.group(1), ln))
        if len(ids) == n:
            return ids
    return None


def _natural(s: str):
    return [int(p) if p.isdigit() else p for p in re.split(r"(\d+)", s)]


def _v(x) -> str:
    if isinstance(x, bool):
        return "true" if x else "false"
    if isinstance(x, float):
        return repr(round(x, 6))
    if isinstance(x, (list, tuple)):
        return "[" + ", ".join(_v(y) for y in x) + "]"
    if isinstance(x, int):
        return str(x)
    return '"' + str(x).replace("\\", "\\\\").replace('"', '\\"') + '"'


def skeleton_toml(name: str, logs: list[tuple[Path, str, list[SensorGuess]]]) -> str:
    """The text of the skeleton ``site.toml`` for the sensors found in ``logs`` (``(path,
    format, sensors)``; an id found twice is declared once, from the first log)."""
    seen: dict[str, tuple[SensorGuess, Path]] = {}
    for path, _, sensors in logs:
        for s in sensors:
            seen.setdefault(s.id, (s, path))
    n = max(len(seen), 1)
    cols = math.ceil(math.sqrt(n))
    rows = math.ceil(n / cols)
    w, h = cols * GRID_SPACING, rows * GRID_SPACING
    lines = [
        f"# site.toml skeleton written by 'onebit init' from {', '.join(p.name for p, _, _ in logs)}.",
        "# Every line marked CHECK is a guess or a placeholder: correct it before trusting a tracker.",
        "# Lengths are in metres. 'onebit check' says what each tracker still needs.",
        f"name = {_v(name)}",
        'units = "m"',
        "# targets = 1          # CHECK: how many people at most (some trackers need it)",
        "",
        "[boundary]",
        "# CHECK: placeholder, the box around the placeholder positions; draw the real floor here",
        f"polygon = {_v([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]])}",
        "",
    ]
    kinds_used = sorted({s.kind for s, _ in seen.values()})
    for kind in kinds_used:
        table, signal, ignore, meaning = KINDS[kind]
        lines += [f"[sensor_types.{kind}]", f"# {meaning}", f'signal = "{signal}"']
        if ignore:
            lines.append("ignore = true          # CHECK: read from the logs, left out of every tracker")
        lines.append("")
    for k, (sid, (s, path)) in enumerate(seen.items()):
        table = KINDS[s.kind][0]
        x = GRID_SPACING * (k % cols + 0.5)
        y = GRID_SPACING * (k // cols + 0.5)
        lines += [
            f"[[{table}]]",
            f"id = {_v(sid)}",
            f'type = "{s.kind}"          # CHECK: guessed from {s.why} ({path.name})',
            f"position = {_v([x, y])}          # CHECK: placeholder position",
            (f"range = {_v(RADIUS)}" if table == "motion_sensors" else f"radius = {_v(RADIUS)}")
            + "          # CHECK: placeholder detection radius",
            "",
        ]
    lines += [
        "# The graph trackers (findinghumo, hmm1, hmm2, residents) need a sensor graph. Once the",
        "# positions are real, uncomment one of:",
        "# [sensor_graph]",
        '# geometry = "connected"          # edges between near sensors, from the positions',
        '# edges = [["a", "b"], ["b", "c"]]  # or the adjacency itself',
        "# entries = []                      # sensors at the doors",
        "# exits = []",
        "",
    ]
    return "\n".join(lines)


def init_dataset(dataset: str | Path, logs: list[str | Path], *, force: bool = False) -> tuple[Path, list]:
    """Write ``DATASET/site.toml``, a skeleton from ``logs`` (module docstring); refuse to
    replace an existing one unless ``force``. The text is checked to load with the site
    loader before it is written (atomically). Returns the path and ``(path, format,
    sensors)`` of every log."""
    out = Path(dataset)
    target = out / "site.toml"
    if target.exists() and not force:
        raise InputError("a site.toml is there already; --force replaces it", file=str(target))
    if not logs:
        raise InputError("no log given (--from LOG [LOG...])", file=str(out))
    found = []
    for log in logs:
        p = Path(log)
        if not p.is_file():
            raise InputError("no such file", file=str(p))
        fmt, sensors = guess_sensors(p)
        if not sensors:
            raise InputError(f"no sensor found in the log (read as {fmt})", file=str(p))
        found.append((p, fmt, sensors))
    text = skeleton_toml(out.resolve().name or "site", found)
    site_from_dict(tomllib.loads(text), source=str(target))  # never write a site that would not load
    out.mkdir(parents=True, exist_ok=True)
    write_text(text, target)
    return target, found
