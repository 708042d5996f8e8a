"""The field checks of ``site.toml`` (:mod:`onebit.core.site`): each value checked and
converted on its own, the error naming its key (``err(key, reason)`` builds the
:class:`~onebit.core.errors.SiteError`).
"""

from __future__ import annotations

import math
from datetime import datetime

import numpy as np
import shapely
from shapely.geometry import Polygon

from onebit.core.errors import bounded


def _shown(value) -> str:
    """A user's value as quoted in a message (bounded: :func:`onebit.core.errors.bounded`)."""
    return bounded(repr(value))


def _number(value, key: str, err, *, lo: float | None = None, positive: bool = False) -> float:
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
        raise err(key, f"must be a finite number, got {_shown(value)}")
    if positive and value <= 0:
        raise err(key, f"must be positive, got {value!r}")
    if lo is not None and value < lo:
        raise err(key, f"must be at least {lo}, got {value!r}")
    return float(value)


def _integer(value, key: str, err, *, lo: int | None = None) -> int:
    """An integer (never a bool, never a float) of at least ``lo``."""
    if not isinstance(value, int) or isinstance(value, bool):
        raise err(key, f"must be an integer, got {_shown(value)}")
    if lo is not None and value < lo:
        raise err(key, f"must be at least {lo}, got {value!r}")
    return value


def _name(value, key: str, err) -> str:
    """An id or name: a non-empty string, or an integer (kept as its decimal text)."""
    if isinstance(value, bool) or not isinstance(value, (str, int)):
        raise err(key, f"must be a string (or an integer), got {_shown(value)}")
    text = str(value)
    if not text.strip():
        raise err(key, "must not be empty")
    return text


def _check_epoch(epoch: str, err) -> None:
    """The epoch is an ISO 8601 date or date-time (``2024-05-01T08:00:00Z``)."""
    try:
        datetime.fromisoformat(epoch.replace("Z", "+00:00"))
    except ValueError:
        raise err(
            "epoch", f"not an ISO 8601 date or date-time (e.g. 2024-05-01T08:00:00Z), got {_shown(epoch)}"
        ) from None


def _sensor_id(table: dict, key: str, seen: set[str], err) -> str:
    if "id" not in table:
        raise err(key + ".id", "missing")
    sid = _name(table["id"], key + ".id", err)
    if sid in seen:
        raise err(key + ".id", f"duplicate sensor id {sid!r}")
    seen.add(sid)
    return sid


def _natural_key(s: str):
    import re

    return [int(p) if p.isdigit() else p for p in re.split(r"(\d+)", s)]


def _geom_points(g):
    if g.geom_type == "Point":
        return [g]
    return list(getattr(g, "geoms", []))


def _unknown(table: dict, allowed: set[str], prefix: str, err) -> None:
    for k in table:
        if k not in allowed:
            raise err(prefix + k, f"unknown key; allowed keys are {sorted(allowed)}")


def _list_of_tables(value, key: str, err) -> list[dict]:
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        raise err(key, "must be an array of tables ([[" + key + "]])")
    return value


def _points(value, key: str, err) -> np.ndarray:
    if value is None:
        raise err(key, "missing")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise err(key, "must be a list of [x, y] number pairs") from None
    if arr.ndim != 2 or arr.shape[1] != 2 or not np.all(np.isfinite(arr)):
        raise err(key, "must be a list of [x, y] number pairs")
    return arr


def _polygon(value, key: str, err) -> Polygon:
    pts = _points(value, key, err)
    if len(pts) < 3:
        raise err(key, f"a polygon needs at least 3 points, got {len(pts)}")
    poly = Polygon(pts)
    if not poly.is_valid:
        raise err(key, f"invalid polygon: {shapely.is_valid_reason(poly)}")
    if poly.area <= 0:
        raise err(key, "polygon has zero area")
    return shapely.orient_polygons(poly) if hasattr(shapely, "orient_polygons") else poly


def _is_matrix(v) -> bool:
    """A non-empty list of equally long lists of numbers (never bools)."""
    return (
        isinstance(v, list)
        and len(v) > 0
        and all(isinstance(r, list) and len(r) == len(v[0]) for r in v)
        and all(isinstance(x, (int, float)) and not isinstance(x, bool) for r in v for x in r)
    )
