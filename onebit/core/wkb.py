"""Geometry columns stored as WKB (the I-state ``regions`` table), parsed and written once per
distinct geometry.

An I-state recurs from stage to stage (a day of a home: 226 000 region rows, 11 000 distinct
regions of ~3 kB each), so a column that encodes or parses every row pays for the same
polygon a thousand times over -- 0.7 GB of WKB bytes and as many shapely objects. Here each
distinct value is handled once and the rows gather it: a polars ``Binary`` column gathered
from its distinct values shares their bytes (its views point into one buffer), and the
parsed geometries are one shapely object per distinct value, repeated by reference.
"""

from __future__ import annotations

import numpy as np
import polars as pl
import shapely


def distinct_codes(col: pl.Series) -> tuple[pl.Series, np.ndarray]:
    """``(values, codes)``: the distinct values of ``col`` in order of first appearance (compared
    by value, exactly) and each row's index into them, ``col == values.gather(codes)``."""
    g = col.rename("v").to_frame().with_row_index("row").group_by("v", maintain_order=True).agg(pl.col("row"))
    codes = np.empty(col.len(), dtype=np.int64)
    rows = g["row"]
    codes[rows.explode().to_numpy()] = np.repeat(np.arange(g.height, dtype=np.int64), rows.list.len().to_numpy())
    return g["v"].rename(col.name), codes


def geometries(col: pl.Series) -> np.ndarray:
    """``shapely.from_wkb`` of a WKB column as an object array, each distinct WKB parsed once
    (rows with the same bytes hold the same geometry object; a null row is ``None``)."""
    values, codes = distinct_codes(col)
    return np.asarray(shapely.from_wkb(values.to_numpy()), dtype=object)[codes]


def wkb_column(geoms: np.ndarray, name: str = "wkb") -> pl.Series:
    """``shapely.to_wkb`` of an object array of geometries as a polars ``Binary`` column,
    each distinct *object* encoded once and its bytes shared by the rows holding it."""
    geoms = np.asarray(geoms, dtype=object)
    if geoms.size == 0:
        return pl.Series(name, [], dtype=pl.Binary)
    _, first, inv = np.unique(
        np.fromiter(map(id, geoms), dtype=np.int64, count=geoms.size), return_index=True, return_inverse=True
    )
    values = pl.Series(name, shapely.to_wkb(geoms[first]), dtype=pl.Binary)
    return values.gather(inv.ravel())
