"""Small pure converters shared by the loggers: frames -> numpy columns, rings, thinning, and
frames -> the Arrow arrays of Rerun's component batches.

Rerun's ``Archetype.columns(...)`` converts a Python list of strips or strings element by
element (tens of microseconds each: 36 s for the 676 000 strips of a 10^6-row beams run). A
``pyarrow`` array of the component's own Arrow type is taken as it is, so the loggers build
those arrays here from flat numpy / polars columns, with no Python work per row:

* :func:`strips_array` -- ``LineStrip2D`` (a list of 2-D points per strip) from flat points
  and per-strip lengths;
* :func:`blobs_array` -- ``Blob`` (encoded images) from a list of bytes;
* :func:`text_array` / :func:`repeat_text` / :func:`choice_text` -- ``Text`` / ``TextLogLevel``
  strings (UTF-8);
* :func:`ring_table` / :func:`region_outlines` -- the outline rings of a set of polygons, and
  the flat points of the outlines of a sequence of polygon indices (a region a track is in, per
  row), gathered with :func:`gather_ranges`.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np
import polars as pl
import shapely
from shapely.geometry.base import BaseGeometry

from onebit.core.lazy import lazy_module

pa = lazy_module("pyarrow")
rr = lazy_module("rerun")


def is_empty(df: pl.DataFrame | None) -> bool:
    return df is None or df.height == 0


def require(df: pl.DataFrame, columns: tuple[str, ...], *, name: str) -> None:
    """Raise naming the frame and the missing columns."""
    missing = [c for c in columns if c not in df.columns]
    if missing:
        raise ValueError(f"{name} frame lacks column(s) {missing}; it has {df.columns}")


def only_tracker(df: pl.DataFrame, tracker: str) -> pl.DataFrame:
    """Rows of ``tracker`` when the frame has a ``tracker`` column, else the frame."""
    if "tracker" not in df.columns:
        return df
    mine = (df.get_column("tracker") == tracker).fill_null(False)
    return df if mine.all() else df.filter(mine)  # a tracker's own table: no copy


def in_time_order(df: pl.DataFrame, column: str = "t") -> pl.DataFrame:
    """``df`` sorted by ``column`` (stable), or ``df`` itself when it is in that order already
    (the readers' and trackers' tables are: one numpy comparison instead of a sort)."""
    t = df.get_column(column).to_numpy()
    if t.size > 1 and not (t[1:] >= t[:-1]).all():
        return df.sort(column, maintain_order=True)
    return df


#: Up to this many distinct keys :func:`groups` filters once per key instead of partitioning.
FEW_GROUPS = 8


def groups(df: pl.DataFrame, key: str) -> list[tuple[str, pl.DataFrame]]:
    """``(key value, rows sorted by t)`` for each value of ``key``, in sorted key order.

    A few values of a string or integer key (at most :data:`FEW_GROUPS`: tracks, regions,
    beams) are one filter each (5x faster than a partition for 2 tracks of 10^5 rows); more,
    one hash partition by ``key``. Rows keep their order either way; each part is then sorted
    by ``t`` only where it is not in order already (the readers' and trackers' tables are): no
    sort of the whole frame on a string key (0.7 s at 10^6 rows)."""
    dtype = df.schema[key]
    keys = df.get_column(key).drop_nulls().unique(maintain_order=True)
    if keys.len() <= FEW_GROUPS and (
        dtype.is_integer() or dtype in (pl.String, pl.Categorical) or isinstance(dtype, pl.Enum)
    ):
        parts = {(k,): df.filter(pl.col(key) == k) for k in keys.to_list()}
    else:
        parts = df.filter(pl.col(key).is_not_null()).partition_by(key, as_dict=True, maintain_order=True)
    out = []
    for k, g in sorted(parts.items(), key=lambda kv: kv[0][0]):
        out.append((str(k[0]), in_time_order(g)))
    return out


def rings(geom: BaseGeometry) -> list[np.ndarray]:
    """Closed ``(n, 2)`` coordinate rings of a polygon, multipolygon or line geometry."""
    out: list[np.ndarray] = []
    for g in getattr(geom, "geoms", [geom]):
        if g.geom_type == "Polygon":
            out.append(np.asarray(g.exterior.coords)[:, :2])
            out.extend(np.asarray(r.coords)[:, :2] for r in g.interiors)
        elif not g.is_empty:
            out.append(np.asarray(shapely.get_coordinates(g)))
    return out


def update_indices(n: int, max_updates: int) -> np.ndarray:
    """At most ``max_updates`` sample indices spread evenly over ``n``, always with the last."""
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    k = min(n, max(1, max_updates))
    return np.unique(np.linspace(0, n - 1, k).round().astype(np.int64))


# --------------------------------------------------------------------------- Arrow component arrays


@functools.cache
def _strip_type():
    """Rerun's Arrow type of a ``LineStrip2D`` batch (``list<fixed_size_list<float32, 2>>``)."""
    return rr.components.LineStrip2DBatch([]).as_arrow_array().type


def gather_ranges(starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Concatenated ``arange(starts[i], starts[i] + lengths[i])`` over ``i``, without a Python loop.

    Examples
    --------
    >>> gather_ranges(np.array([5, 0, 2]), np.array([2, 0, 3])).tolist()
    [5, 6, 2, 3, 4]
    """
    starts = np.asarray(starts, np.int64).reshape(-1)
    lengths = np.asarray(lengths, np.int64).reshape(-1)
    total = int(lengths.sum())
    if total == 0:
        return np.zeros(0, np.int64)
    before = np.cumsum(lengths) - lengths  # output position of each range's first element
    return np.repeat(starts - before, lengths) + np.arange(total, dtype=np.int64)


def strips_array(points: np.ndarray, lengths: np.ndarray | int) -> pa.ListArray:
    """A ``LineStrip2D`` batch as one Arrow array: strip ``i`` is the next ``lengths[i]`` rows of
    ``points`` (``(m, 2)``, ``m = sum(lengths)``); an int ``lengths`` gives equal strips.

    Equal to ``rr.components.LineStrip2DBatch([strip_0, strip_1, ...]).as_arrow_array()``
    (tested), built from the flat points in one go: pass it as ``strips=`` to
    ``rr.LineStrips2D.columns``, then ``.partition(strips per row)``.
    """
    pts = np.ascontiguousarray(np.asarray(points, np.float32).reshape(-1, 2))
    if np.isscalar(lengths) or np.ndim(lengths) == 0:
        k = int(lengths)
        if k <= 0 or len(pts) % k:
            raise ValueError(f"{len(pts)} points cannot be cut into strips of {k}")
        offsets = np.arange(0, len(pts) + 1, k, dtype=np.int32)
    else:
        lens = np.asarray(lengths, np.int64).reshape(-1)
        if (lens < 0).any() or int(lens.sum()) != len(pts):
            raise ValueError(f"strip lengths sum to {int(lens.sum())}, not to the {len(pts)} points given")
        offsets = np.zeros(len(lens) + 1, np.int32)
        np.cumsum(lens, out=offsets[1:])
    typ = _strip_type()
    inner = pa.FixedSizeListArray.from_arrays(pa.array(pts.reshape(-1)), type=typ.value_type)
    return pa.ListArray.from_arrays(pa.array(offsets), inner, type=typ)


@functools.cache
def _blob_type():
    """Rerun's Arrow type of a ``Blob`` batch (``list<uint8 not null>``)."""
    return rr.components.BlobBatch([]).as_arrow_array().type


def blobs_array(blobs: Sequence[bytes]) -> pa.ListArray:
    """A ``Blob`` batch (encoded images) as one Arrow array, the bytes joined in one copy: pass
    it as ``blob=`` to ``rr.EncodedImage.columns``. Equal to
    ``rr.components.BlobBatch(blobs).as_arrow_array()`` (tested), which converts blob by blob
    (13 us each: 4 s for the 330 000 fill images of a 10^6-row beams run)."""
    lens = np.fromiter(map(len, blobs), dtype=np.int64, count=len(blobs))
    if int(lens.sum()) > np.iinfo(np.int32).max:  # 32-bit offsets: Rerun's own conversion
        return rr.components.BlobBatch(list(blobs)).as_arrow_array()
    offsets = np.zeros(len(blobs) + 1, np.int32)
    np.cumsum(lens, out=offsets[1:])
    body = np.frombuffer(b"".join(blobs), dtype=np.uint8)
    return pa.ListArray.from_arrays(pa.array(offsets), pa.array(body), type=_blob_type())


def text_array(values: pl.Series | Sequence[str]) -> pa.StringArray:
    """UTF-8 Arrow strings (Rerun's ``Text`` / ``TextLogLevel`` type) of a polars column or a list.

    A polars column without nulls is exported as Arrow large strings and its buffers taken over
    with 32-bit offsets, with no Arrow ``cast``: the first ``cast`` in a process imports
    ``pyarrow.compute`` (0.1-0.2 s, more than the rest of a recording's texts)."""
    if isinstance(values, pl.Series):
        arr = values.cast(pl.String).rechunk().to_arrow(compat_level=pl.CompatLevel.oldest())
        if arr.type == pa.utf8():
            return arr
        if arr.type != pa.large_utf8() or arr.null_count or arr.offset:
            return arr.cast(pa.utf8())
        _, offsets, data = arr.buffers()
        off = np.frombuffer(offsets, np.int64, count=len(arr) + 1)
        if off[-1] - off[0] > np.iinfo(np.int32).max:
            return arr.cast(pa.utf8())
        off32 = (off - off[0]).astype(np.int32)
        body = data.slice(int(off[0]), int(off[-1] - off[0])) if data is not None else pa.py_buffer(b"")
        return pa.StringArray.from_buffers(len(arr), pa.py_buffer(off32.tobytes()), body)
    return pa.array(list(values), type=pa.utf8())


def repeat_text(text: str, n: int) -> pa.StringArray:
    """``n`` copies of ``text`` as UTF-8 Arrow strings (a level or label shared by every row)."""
    raw = str(text).encode()
    offsets = np.arange(n + 1, dtype=np.int32) * np.int32(len(raw))
    return pa.StringArray.from_buffers(n, pa.py_buffer(offsets.tobytes()), pa.py_buffer(raw * n))


def choice_text(options: Sequence[str], index: np.ndarray) -> pa.StringArray:
    """``options[index[k]]`` for every row ``k`` as UTF-8 Arrow strings: a text column with a
    few distinct values (a crossing's ``"a forward"`` / ``"a^-1 backward"``) gathered by polars
    from the few options (no string per row in Python), then taken over by :func:`text_array`
    (about 3x faster than cutting the bytes with numpy). Equal to :func:`text_array` of the
    same list."""
    index = np.asarray(index, np.int64).reshape(-1)
    if index.size and (index.min() < 0 or index.max() >= len(options)):
        raise ValueError(f"choice_text: an index outside the {len(options)} options")
    picked = pl.Series("s", [str(o) for o in options], dtype=pl.String).gather(index.astype(np.uint32, copy=False))
    return text_array(picked)


def ring_table(polygons: Sequence[BaseGeometry]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The outline rings of each polygon, flat: ``(points (P, 2), ring lengths (R,), first ring of
    each polygon (p,), rings of each polygon (p,))``; rings as :func:`rings` gives them."""
    per = [rings(g) for g in polygons]
    flat = [r for rs in per for r in rs]
    points = np.concatenate(flat).astype(np.float64).reshape(-1, 2) if flat else np.zeros((0, 2))
    ring_len = np.array([len(r) for r in flat], np.int64)
    count = np.array([len(rs) for rs in per], np.int64)
    first = np.cumsum(count) - count
    return points, ring_len, first, count


def region_outlines(table: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], k: np.ndarray):
    """The outlines of polygons ``k`` (indices into the polygons of ``table``, one per row):
    ``(points (float32), strip lengths, strips per row)`` for :func:`strips_array` and ``.partition``.

    The rings of a polygon are contiguous in the table, so the points are one gather of a range
    per row (in float32, the type of Rerun's strips: no second copy); the ring lengths need a
    gather per ring only when some polygon has holes or parts (else they are the polygons')."""
    points, ring_len, first, count = table
    k = np.asarray(k, np.int64).reshape(-1)
    ends = np.zeros(len(ring_len) + 1, np.int64)
    np.cumsum(ring_len, out=ends[1:])
    poly_start, poly_len = ends[first], ends[first + count] - ends[first]
    pts = np.asarray(points, np.float32).reshape(-1, 2)[gather_ranges(poly_start[k], poly_len[k])]
    if (count == 1).all():
        lengths = poly_len[k]
    else:
        lengths = ring_len[gather_ranges(first[k], count[k])]
    return pts, lengths, count[k]
