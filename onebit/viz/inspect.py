"""Reading back ``.rrd`` and ``.rbl`` files: which entities (with which archetypes) and
stores they hold, what a blueprint's views show, and whether a file verifies.

Used by the blueprint builder (:func:`onebit.viz.blueprint.save_run_blueprint` reads what a
run logged) and by tests to check recordings without a viewer. Entity paths and store ids are
read with the SDK's :class:`rerun.chunk.RrdReader`; if that is unavailable, ``rerun rrd print
--verbose`` output is parsed. :func:`verify` runs ``rerun rrd verify``.
"""

from __future__ import annotations

import math
import re
import shutil
import subprocess
import sys
import uuid
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

_CHUNK_LINE = re.compile(r"^Chunk\(.*?\) with \d+ rows \(.*?\) - (?P<path>.+?) - data columns:")
_STORE_ID = re.compile(r'store_id: StoreId\(\s*(?P<kind>\w+),\s*"(?P<app>[^"]*)",\s*"(?P<rec>[^"]*)",\s*\)', re.S)


def rerun_binary() -> Path:
    """The ``rerun`` CLI of this interpreter's environment, else the one on ``PATH``."""
    local = Path(sys.executable).parent / "rerun"
    if local.exists():
        return local
    found = shutil.which("rerun")
    if found is None:
        raise FileNotFoundError(f"no rerun CLI next to {sys.executable} nor on PATH")
    return Path(found)


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(rerun_binary()), *args], capture_output=True, text=True, check=False)


def _clean(path: str) -> str:
    return path.strip().lstrip("/")


#: Root entities of a blueprint store; ``rerun rrd print`` lists them among the recording's.
_BLUEPRINT_ROOTS = {"view", "container", "viewport", "time_panel", "blueprint_panel", "selection_panel", "top_panel"}


def _is_internal(path: str) -> bool:
    return path.startswith("__")


def entity_paths(rrd_path: str | Path) -> set[str]:
    """Entity paths (no leading ``/``, escaped as built by :mod:`onebit.viz.paths`) of the
    first recording store in ``rrd_path``, without Rerun's internal ``__properties``."""
    try:
        from rerun.chunk import RrdReader
    except ImportError:  # pragma: no cover - older SDKs without a reader
        return _entity_paths_cli(rrd_path)
    out = {_clean(c.entity_path) for c in RrdReader(str(rrd_path)).stream()}
    return {p for p in out if p and not _is_internal(p)}


def _entity_paths_cli(rrd_path: str | Path) -> set[str]:
    proc = _run("rrd", "print", "--verbose", str(rrd_path))
    if proc.returncode != 0:
        raise RuntimeError(f"rerun rrd print {rrd_path} failed: {proc.stderr.strip()}")
    found = {_clean(m["path"]) for line in proc.stdout.splitlines() if (m := _CHUNK_LINE.match(line))}
    return {p for p in found if p and not _is_internal(p) and p.split("/")[0] not in _BLUEPRINT_ROOTS}


def store_ids(rrd_path: str | Path) -> list[tuple[str, str]]:
    """``(application_id, recording_id)`` of every recording store in ``rrd_path``."""
    try:
        from rerun.chunk import RrdReader
    except ImportError:  # pragma: no cover - older SDKs without a reader
        return _store_ids_cli(rrd_path)
    return [(s.application_id, s.recording_id) for s in RrdReader(str(rrd_path)).recordings()]


def _store_ids_cli(rrd_path: str | Path) -> list[tuple[str, str]]:
    proc = _run("rrd", "print", str(rrd_path))
    if proc.returncode != 0:
        raise RuntimeError(f"rerun rrd print {rrd_path} failed: {proc.stderr.strip()}")
    ids = [(m["app"], m["rec"]) for m in _STORE_ID.finditer(proc.stdout) if m["kind"] == "Recording"]
    return list(dict.fromkeys(ids))


def verify(rrd_path: str | Path) -> None:
    """Run ``rerun rrd verify``; raise ``RuntimeError`` with its output unless it succeeds."""
    rrd_path = Path(rrd_path)
    if not rrd_path.is_file():
        raise FileNotFoundError(f"no recording at {rrd_path}")
    proc = _run("rrd", "verify", str(rrd_path))
    if proc.returncode != 0:
        raise RuntimeError(
            f"rerun rrd verify {rrd_path} failed (exit {proc.returncode}): {(proc.stderr or proc.stdout).strip()}"
        )


# --------------------------------------------------------------------------- archetypes


def _reader(path: str | Path):
    from rerun.chunk import RrdReader  # the SDK's reader (rerun-sdk >= 0.30)

    return RrdReader(str(path))


def list_min_max(column) -> tuple[float | None, float | None]:
    """``(min, max)`` of the values of an Arrow list column of float64 (``Scalars:scalars``),
    as ``pyarrow.compute.min_max`` of its flattened values gives them (nulls skipped, NaNs
    ignored unless every value is NaN, ``None`` without a value), read from the Arrow buffers
    with numpy: ``pyarrow.compute`` takes 0.1-0.2 s to import, more than the blueprint's
    other work; another value type goes through it."""
    import pyarrow as pa

    if isinstance(column, pa.ChunkedArray):
        parts = [list_min_max(c) for c in column.chunks]
        lo = [p[0] for p in parts if p[0] is not None]
        hi = [p[1] for p in parts if p[1] is not None]
        if not lo:
            return None, None
        real_lo, real_hi = [v for v in lo if v == v], [v for v in hi if v == v]
        return (min(real_lo) if real_lo else math.nan), (max(real_hi) if real_hi else math.nan)
    typ = column.type
    if not (pa.types.is_list(typ) or pa.types.is_large_list(typ)) or typ.value_type != pa.float64():
        import pyarrow.compute as pc

        mm = pc.min_max(pc.list_flatten(column))
        return mm["min"].as_py(), mm["max"].as_py()
    n = len(column)
    if n == 0:
        return None, None
    width = 8 if pa.types.is_large_list(typ) else 4
    off = np.frombuffer(
        column.buffers()[1], np.int64 if width == 8 else np.int32, count=n + 1, offset=width * column.offset
    )
    values = column.values
    lo_i, hi_i = int(off[0]), int(off[-1])
    if hi_i <= lo_i:
        return None, None
    vb = values.buffers()
    data = np.frombuffer(vb[1], np.float64, count=hi_i - lo_i, offset=8 * (values.offset + lo_i))
    if values.null_count and vb[0] is not None:
        bits = np.unpackbits(np.frombuffer(vb[0], np.uint8), bitorder="little")
        data = data[bits[values.offset + lo_i : values.offset + hi_i].astype(bool)]
    if data.size == 0:
        return None, None
    real = data[~np.isnan(data)]
    if real.size == 0:
        return math.nan, math.nan
    return float(real.min()), float(real.max())


def scalar_ranges(rrd_paths: str | Path | Iterable[str | Path]) -> dict[str, tuple[float, float]]:
    """``{entity path: (min, max)}`` of the Scalars each entity logged (NaNs ignored), over the
    first recording store of each file; only the chunks holding Scalars are read
    (:func:`list_min_max`: no ``pyarrow.compute``)."""
    files = [rrd_paths] if isinstance(rrd_paths, (str, Path)) else list(rrd_paths)
    out: dict[str, tuple[float, float]] = {}
    for f in files:
        reader = _reader(f)
        if not reader.recordings():
            continue
        store = reader.store()  # lazy: only the chunks holding Scalars are loaded
        if not any(c.component == "Scalars:scalars" for c in store.schema().component_columns()):
            continue
        for chunk in store.stream().filter(components="Scalars:scalars"):
            rb = chunk.to_record_batch()
            if "Scalars:scalars" not in rb.schema.names:
                continue
            lo, hi = list_min_max(rb.column("Scalars:scalars"))
            if lo is None:
                continue
            path = _clean(chunk.entity_path)
            old = out.get(path, (lo, hi))
            out[path] = (min(old[0], lo), max(old[1], hi))
    return out


def entity_archetypes(rrd_paths: str | Path | Iterable[str | Path]) -> dict[str, frozenset[str]]:
    """``{entity path: archetype names}`` over the first recording store of each file, e.g.
    ``{"truth/A": {"Ellipses2D", "Points2D"}, "sensors/p1": {"StateChange", "StateConfiguration"}}``.

    Paths have no leading ``/`` and are escaped as built by :mod:`onebit.viz.paths`; Rerun's
    internal ``__properties`` is left out.
    """
    files = [rrd_paths] if isinstance(rrd_paths, (str, Path)) else list(rrd_paths)
    found: dict[str, set[str]] = {}
    for f in files:
        reader = _reader(f)
        try:  # the store's schema: read from the file's chunk index, no chunk loaded (ms, not s)
            columns = reader.store().schema().component_columns() if reader.recordings() else []
        except (AttributeError, TypeError, ValueError):  # pragma: no cover - an SDK without the lazy store
            columns = None
        if columns is None:  # pragma: no cover
            _archetypes_by_chunks(reader, found)
            continue
        for col in columns:
            path = _clean(col.entity_path)
            if col.is_property or not path or _is_internal(path):
                continue
            kinds = found.setdefault(path, set())
            if col.archetype:
                kinds.add(str(col.archetype).rsplit(".", 1)[-1])
    return {p: frozenset(k) for p, k in found.items()}


def _archetypes_by_chunks(reader, found: dict[str, set[str]]) -> None:
    """:func:`entity_archetypes` of one file by reading every chunk (the SDK's schema unavailable)."""
    for chunk in reader.stream():
        path = _clean(chunk.entity_path)
        if not path or _is_internal(path):
            continue
        kinds = found.setdefault(path, set())
        for fld in chunk.to_record_batch().schema:
            arch = (fld.metadata or {}).get(b"rerun:archetype")
            if arch:
                kinds.add(arch.decode().rsplit(".", 1)[-1])


# --------------------------------------------------------------------------- blueprints


@dataclass(frozen=True)
class ViewInfo:
    """One view of a blueprint as read back from the file."""

    name: str
    kind: str  # Rerun's class identifier: "2D", "TimeSeries", "TextLog", "StateTimeline", ...
    origin: str
    query: tuple[str, ...]
    #: entity path -> {"visible": bool} and/or {"time_range": (start_s, end_s)}
    overrides: dict[str, dict] = field(default_factory=dict)


def _first(rb, name: str):
    if name not in rb.schema.names:
        return None
    vals = [v for v in rb.column(name).to_pylist() if v is not None]
    if not vals:
        return None
    v = vals[-1]
    return v[0] if isinstance(v, list) and len(v) == 1 else v


def blueprint_views(path: str | Path) -> list[ViewInfo]:
    """Every view of the (first) blueprint store of ``path`` (an ``.rbl``, or an ``.rrd`` that
    holds a blueprint), with its contents query and its per-entity overrides."""
    reader = _reader(path)
    stores = reader.blueprints()
    if not stores:
        raise ValueError(f"{path} holds no blueprint")
    views: dict[str, dict] = {}
    for chunk in reader.stream(store=stores[0]):
        ep = _clean(chunk.entity_path)
        parts = ep.split("/")
        if len(parts) < 2 or parts[0] != "view":
            continue
        v = views.setdefault(parts[1], {"overrides": {}})
        rb = chunk.to_record_batch()
        if len(parts) == 2:
            v["name"] = _first(rb, "ViewBlueprint:display_name") or ""
            v["kind"] = _first(rb, "ViewBlueprint:class_identifier") or ""
            v["origin"] = _clean(_first(rb, "ViewBlueprint:space_origin") or "/")
        elif parts[2:] == ["ViewContents"]:
            q = rb.column("ViewContents:query").to_pylist()[-1] if "ViewContents:query" in rb.schema.names else []
            v["query"] = tuple(q or ())
        elif parts[2:4] == ["ViewContents", "overrides"] and parts[-1] == "visualizers":
            entity = "/".join(parts[4:-1])
            o = v["overrides"].setdefault(entity, {})
            vis = _first(rb, "EntityBehavior:visible")
            if vis is not None:
                o["visible"] = bool(vis)
            ranges = _first(rb, "VisibleTimeRanges:ranges")
            if ranges:
                r = ranges[0] if isinstance(ranges, list) else ranges
                o["time_range"] = (r["range"]["start"] / 1e9, r["range"]["end"] / 1e9)
    return [
        ViewInfo(v.get("name", ""), v.get("kind", ""), v.get("origin", ""), v.get("query", ()), v["overrides"])
        for v in views.values()
    ]


def _rule(expr: str) -> tuple[bool, str, bool]:
    """``(include, path, subtree)`` of one query expression (``"+ a/**"``, ``"- a"``, ``"a"``)."""
    e = expr.strip()
    include = not e.startswith("-")
    e = e.lstrip("+-").strip()
    subtree = e.endswith("/**") or e == "**"
    e = e[:-3] if e.endswith("/**") else ("" if e == "**" else e)
    return include, _clean(e), subtree


def query_rules(query: Iterable[str], *, origin: str = "/") -> list[tuple[bool, str, bool]]:
    """Parsed rules of a contents query, ``$origin`` replaced by ``origin``."""
    origin = _clean(origin)
    out = []
    for expr in query:
        expr = expr.replace("$origin", "/" + origin if origin else "")
        out.append(_rule(expr))
    return out


def rule_base(rule: tuple[bool, str, bool]) -> str:
    """The entity path a rule names (``""`` = the root)."""
    return rule[1]


def query_includes(query: Iterable[str], path: str, *, origin: str = "/") -> bool:
    """Whether Rerun's entity query ``query`` includes ``path``: the most specific matching rule
    wins (deeper paths, then an exact rule over a subtree rule), the last of equals; no match
    excludes (https://rerun.io/docs/reference/entity-queries)."""
    path = _clean(path)
    best: tuple[tuple[int, int], bool] | None = None
    for include, base, subtree in query_rules(query, origin=origin):
        if subtree:
            hit = base == "" or path == base or path.startswith(base + "/")
        else:
            hit = path == base
        if not hit:
            continue
        key = (len(base.split("/")) if base else 0, 0 if subtree else 1)
        if best is None or key >= best[0]:
            best = (key, include)
    return bool(best and best[1])


def component_rows(rrd_paths: str | Path | Iterable[str | Path], entity: str, component: str) -> list:
    """Every row of ``component`` (e.g. ``"Points2D:labels"``) logged on ``entity``, static rows
    first, as Python values (one list per row)."""
    files = [rrd_paths] if isinstance(rrd_paths, (str, Path)) else list(rrd_paths)
    static, timed = [], []
    for f in files:
        for chunk in _reader(f).stream():
            if _clean(chunk.entity_path) != _clean(entity):
                continue
            rb = chunk.to_record_batch()
            if component in rb.schema.names:
                (static if chunk.is_static else timed).extend(rb.column(component).to_pylist())
    return static + timed


def timed_rows(
    rrd_paths: str | Path | Iterable[str | Path], entity: str, component: str, *, timeline: str = "t"
) -> list[tuple[float, object]]:
    """``(t in seconds, value)`` of every timed row of ``component`` on ``entity``, sorted by
    ``t`` (static rows left out; ``timeline`` a duration or timestamp timeline in ns)."""
    import pyarrow as pa

    files = [rrd_paths] if isinstance(rrd_paths, (str, Path)) else list(rrd_paths)
    out: list[tuple[float, object]] = []
    for f in files:
        for chunk in _reader(f).stream():
            if chunk.is_static or _clean(chunk.entity_path) != _clean(entity):
                continue
            rb = chunk.to_record_batch()
            if component not in rb.schema.names:
                continue
            t = rb.column(timeline).cast(pa.int64()).to_pylist()
            out += [(ns / 1e9, v) for ns, v in zip(t, rb.column(component).to_pylist())]
    return sorted(out, key=lambda r: r[0])


def blueprint_tabs(path: str | Path) -> list[str]:
    """Names of the children of a blueprint's root container, in order (the tabs of a layout
    whose root is a ``Tabs`` container); the root container's own name first when it has one."""
    reader = _reader(path)
    stores = reader.blueprints()
    if not stores:
        raise ValueError(f"{path} holds no blueprint")
    containers: dict[str, dict] = {}
    views: dict[str, str] = {}
    root = None
    for chunk in reader.stream(store=stores[0]):
        ep = _clean(chunk.entity_path)
        rb = chunk.to_record_batch()
        if ep == "viewport":
            rid = _first(rb, "ViewportBlueprint:root_container")
            if rid is not None:
                root = str(uuid.UUID(bytes=bytes(rid)))
        elif ep.startswith("container/") and ep.count("/") == 1:
            c = containers.setdefault(ep.split("/")[1], {})
            c["name"] = _first(rb, "ContainerBlueprint:display_name") or c.get("name", "")
            if "ContainerBlueprint:contents" in rb.schema.names:
                c["contents"] = rb.column("ContainerBlueprint:contents").to_pylist()[-1] or []
        elif ep.startswith("view/") and ep.count("/") == 1:
            views[ep.split("/")[1]] = _first(rb, "ViewBlueprint:display_name") or ""
    if root is None or root not in containers:
        return []

    def name(ref: str) -> str:
        kind, _, ident = ref.partition("/")
        return containers.get(ident, {}).get("name", "") if kind == "container" else views.get(ident, "")

    return [name(ref) for ref in containers[root].get("contents", [])]


def recording_rows(rrd_paths: str | Path | Iterable[str | Path]) -> dict[tuple[str, str, str], list[tuple]]:
    """Every row of every component in the first recording store of each file, for comparing
    two recordings content for content: ``{(entity, component, component type): rows}``, a
    row being ``(timelines, value)`` with ``timelines`` a sorted tuple of ``(name, ns)``
    (empty for static rows). Rows are in time order, ties (and static rows) in the order they
    were logged (row id); row and chunk ids themselves are left out, so two files with the
    same content give equal results however their rows were cut into chunks."""
    files = [rrd_paths] if isinstance(rrd_paths, (str, Path)) else list(rrd_paths)
    found: dict[tuple[str, str, str], list[tuple]] = {}
    for f in files:
        for chunk in _reader(f).stream():
            entity = _clean(chunk.entity_path)
            if _is_internal(entity):
                continue
            rb = chunk.to_record_batch()
            row_ids = rb.column(0).to_pylist() if rb.schema.field(0).metadata.get(b"rerun:kind") == b"control" else None
            times, data = [], []
            for i, fld in enumerate(rb.schema):
                kind = (fld.metadata or {}).get(b"rerun:kind")
                if kind == b"index":
                    times.append((fld.name, rb.column(i).cast("int64").to_pylist()))
                elif kind == b"data":
                    data.append((fld, rb.column(i).to_pylist()))
            for fld, values in data:
                key = (entity, fld.name, (fld.metadata or {}).get(b"rerun:component_type", b"").decode())
                rows = found.setdefault(key, [])
                for r, value in enumerate(values):
                    if value is None:
                        continue
                    stamp = tuple(sorted((name, ts[r]) for name, ts in times))
                    rows.append((stamp, row_ids[r] if row_ids else r, value))
    return {
        key: [(stamp, value) for stamp, _, value in sorted(rows, key=lambda row: (row[0], row[1]))]
        for key, rows in found.items()
    }
