"""Many entities logged from one set of flat columns: a cost per row, not per entity.

A tracker's table holds many tracks (2 000 tracklets in a 10^5-row proximity log), and each
track is several entities (``<tracker>/tracks/<track>`` and its ``/trail``, ``/path``...). Built
one track at a time through Rerun's archetype converters (``rr.Points2D.from_fields(...)``,
``rr.LineStrips2D.columns(...)``, ``rr.TimeColumn(...)``), each entity costs 0.5-1 ms of Python
before Rerun sees it: 2.5 ms a track, seconds a run. Here the converters run **once per table**
on the rows of all tracks together, and each entity is then a zero-copy slice of those Arrow
arrays handed to ``rec.log(..., static=True)`` (its style) and ``rec.send_columns`` (its rows):
about 0.03 ms per Rerun call. What the recording holds is unchanged -- the same entities,
components, descriptors, values and times as the per-track calls (tested against them in
``tests/viz/test_bulk.py``).

* :func:`track_spans` -- a table's rows grouped by a key (tracks, regions) as one sort: the
  frame in (key, ``t``) order and the row offsets of each key;
* :func:`log_styles` -- a static style per entity: the components of a template archetype,
  with some components taking one row per entity from a bulk array (colours, labels);
* :func:`send_spans` -- the time-indexed rows of each entity, sliced from the columns of all rows.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import polars as pl

from onebit.core.lazy import lazy_module
from onebit.viz import paths
from onebit.viz._series import FEW_GROUPS, in_time_order

pa = lazy_module("pyarrow")
rr = lazy_module("rerun")


class ArrowColumn:
    """A component batch (static log) or column (``send_columns``) already in Rerun's Arrow
    form: the ``component_descriptor`` / ``as_arrow_array`` pair both calls read."""

    __slots__ = ("array", "descriptor")

    def __init__(self, descriptor, array) -> None:
        self.descriptor = descriptor
        self.array = array

    def component_descriptor(self):
        return self.descriptor

    def as_arrow_array(self):
        return self.array


class TimeArrow:
    """A time index column already in Arrow form (``rr.TimeColumn``'s ``timeline_name`` /
    ``as_arrow_array`` pair)."""

    __slots__ = ("array", "timeline")

    def __init__(self, timeline: str, array) -> None:
        self.timeline = timeline
        self.array = array

    def timeline_name(self) -> str:
        return self.timeline

    def as_arrow_array(self):
        return self.array


def time_array(seconds: np.ndarray):
    """The ``t`` index of rows at ``seconds`` as Arrow durations (ns), exactly as
    :func:`onebit.viz.paths.time_column` converts them."""
    return paths.time_column(np.asarray(seconds, np.float64)).as_arrow_array()


def described(archetype) -> list[ArrowColumn]:
    """The components of an archetype instance (descriptor and Arrow batch), in its order."""
    return [ArrowColumn(b.component_descriptor(), b.as_arrow_array()) for b in archetype.as_component_batches()]


def column_arrays(columns) -> list[ArrowColumn]:
    """The columns of ``Archetype.columns(...)`` (partitioned) as descriptor and list array."""
    return [ArrowColumn(c.component_descriptor(), c.as_arrow_array()) for c in columns]


def color_array(colors: Sequence) -> pa.Array | None:
    """One Rerun colour (``Color``, packed RGBA) per entry of ``colors`` (tuples), converted
    once; ``None`` when every entry is ``None`` (no colour component, as ``colors=None`` in
    an archetype)."""
    colors = list(colors)
    if all(c is None for c in colors):
        return None
    if any(c is None for c in colors):
        raise ValueError("color_array: some entities have a colour and others none")
    return rr.components.ColorBatch(colors).as_arrow_array()


def text_batch(texts: Sequence[str]) -> pa.Array:
    """One Rerun text (``Text``) per entry of ``texts``, converted once."""
    return rr.components.TextBatch([str(s) for s in texts]).as_arrow_array()


@dataclass(frozen=True)
class Spans:
    """Rows of a table grouped by a key: ``frame`` in (key, ``t``) order, the key of each group
    (``str`` of its value, groups in sorted key order, as :func:`onebit.viz._series.groups`
    yields them) and the row offsets ``bounds`` (``(k + 1,)``: group ``i`` is rows
    ``bounds[i]:bounds[i + 1]``)."""

    frame: pl.DataFrame
    keys: list[str]
    bounds: np.ndarray

    @property
    def lengths(self) -> np.ndarray:
        return np.diff(self.bounds)

    def group_of_rows(self) -> np.ndarray:
        """``(n,)`` group index of each row of ``frame``."""
        return np.repeat(np.arange(len(self.keys)), self.lengths)


def track_spans(df: pl.DataFrame, key: str = "track", *, time: str = "t") -> Spans:
    """``df`` without rows of a null ``key``, grouped by ``key``: the groups of
    :func:`onebit.viz._series.groups` (sorted key order; each group's rows in ``time`` order,
    ties in table order) as one frame and offsets. A few keys (at most
    :data:`~onebit.viz._series.FEW_GROUPS`: regions, a few tracks) are a filter each, as in
    ``groups``; more are one stable radix sort of the keys' codes (after a sort by time when
    some key's rows are out of time order) and one gather, and nothing is moved when the rows
    are in (key, time) order already -- no partition and no work per group."""
    if df.get_column(key).null_count():
        df = df.filter(pl.col(key).is_not_null())
    values = df.get_column(key)
    distinct = sorted(values.unique().to_list())  # Python's order, as groups()
    keys = [str(k) for k in distinct]
    if len(set(keys)) != len(keys):  # two values with one text (never for str / int keys)
        raise ValueError(f"{key} values {keys} are not distinct as text")
    bounds = np.zeros(len(keys) + 1, np.int64)
    if 1 < len(keys) <= FEW_GROUPS:  # a filter per key (polars, in parallel) beats a sort and a gather
        parts = [in_time_order(df.filter(pl.col(key) == k), time) for k in distinct]
        np.cumsum([g.height for g in parts], out=bounds[1:])
        return Spans(frame=pl.concat(parts, rechunk=True), keys=keys, bounds=bounds)
    code = values.cast(pl.String).cast(pl.Enum(keys)).to_physical().to_numpy()
    if len(keys) <= np.iinfo(np.uint16).max:  # numpy's stable sort of 16-bit keys is a radix sort
        code = code.astype(np.uint16, copy=False)
    t = df.get_column(time).to_numpy()
    by_key = len(keys) < 2 or bool((code[1:] >= code[:-1]).all())
    order = None if by_key else np.argsort(code, kind="stable")
    c, tt = (code, t) if order is None else (code[order], t[order])
    if tt.size > 1 and not ((tt[1:] >= tt[:-1]) | (c[1:] != c[:-1])).all():  # some key's rows out of time order
        by_t = np.argsort(t, kind="stable")
        order = by_t[np.argsort(code[by_t], kind="stable")]
    if order is not None:
        df = df[order]
    np.cumsum(np.bincount(code, minlength=len(keys)), out=bounds[1:])
    return Spans(frame=df, keys=keys, bounds=bounds)


def log_styles(
    rec: rr.RecordingStream,
    entities: Sequence[str],
    template,
    per_entity: Mapping[str, pa.Array] | None = None,
    *,
    which: Sequence[int] | None = None,
) -> None:
    """``rec.log(entities[i], style_i, static=True)`` for each ``i`` of ``which`` (default: all):
    ``style_i`` holds the components of ``template`` (an archetype instance, or several logged
    together), where a component named in ``per_entity`` (``"Points2D:colors"``) is row ``i`` of
    that array instead."""
    templates = template if isinstance(template, (list, tuple)) else [template]
    base = [c for one in templates for c in described(one)]
    per_entity = {k: v for k, v in (per_entity or {}).items() if v is not None}
    names = {c.descriptor.component for c in base}
    unknown = set(per_entity) - names
    if unknown:
        kinds = "/".join(type(one).__name__ for one in templates)
        raise ValueError(f"log_styles: {sorted(unknown)} are not components of {kinds} ({sorted(names)})")
    for i in range(len(entities)) if which is None else which:
        style = [
            ArrowColumn(c.descriptor, per_entity[c.descriptor.component].slice(i, 1))
            if c.descriptor.component in per_entity
            else c
            for c in base
        ]
        rec.log(entities[i], style, static=True)


def send_spans(
    rec: rr.RecordingStream,
    entities: Sequence[str],
    times,
    columns: Sequence[ArrowColumn],
    starts: np.ndarray,
    stops: np.ndarray,
    *,
    timeline: str = paths.TIMELINE,
) -> None:
    """``rec.send_columns(entities[i], rows starts[i]:stops[i])`` for every entity with rows:
    ``times`` (Arrow, one per row) and each of ``columns`` (list arrays, one entry per row) are
    sliced, not copied (rows of a group: ``starts = bounds[:-1]``, ``stops = bounds[1:]``)."""
    for c in columns:
        if len(c.array) != len(times):
            raise ValueError(f"send_spans: column {c.descriptor.component} has {len(c.array)} rows, times {len(times)}")
    for i, (lo, hi) in enumerate(zip(np.asarray(starts).tolist(), np.asarray(stops).tolist())):
        if hi <= lo:
            continue
        n = hi - lo
        rec.send_columns(
            entities[i],
            indexes=[TimeArrow(timeline, times.slice(lo, n))],
            columns=[ArrowColumn(c.descriptor, c.array.slice(lo, n)) for c in columns],
        )
