"""Small pure converters shared by the loggers: frames -> numpy columns, rings, thinning."""

from __future__ import annotations

import numpy as np
import polars as pl
import shapely
from shapely.geometry.base import BaseGeometry


def is_empty(df: pl.DataFrame | None) -> bool:
    return df is None or df.height == 0


def require(df: pl.DataFrame, columns: tuple[str, ...], *, name: str) -> None:
    """Raise naming the frame and the missing columns."""
    missing = [c for c in columns if c not in df.columns]
    if missing:
        raise ValueError(f"{name} frame lacks column(s) {missing}; it has {df.columns}")


def only_tracker(df: pl.DataFrame, tracker: str) -> pl.DataFrame:
    """Rows of ``tracker`` when the frame has a ``tracker`` column, else the frame."""
    return df.filter(pl.col("tracker") == tracker) if "tracker" in df.columns else df


def groups(df: pl.DataFrame, key: str) -> list[tuple[str, pl.DataFrame]]:
    """``(key value, rows sorted by t)`` for each value of ``key``, in sorted key order."""
    df = df.filter(pl.col(key).is_not_null())
    parts = df.sort([key, "t"]).partition_by(key, as_dict=True, maintain_order=True)
    return [(str(k[0]), g) for k, g in parts.items()]


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
