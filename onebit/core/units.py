"""Units: the one place where config lengths meet the site's units.

A site's geometry (``site.toml``), its logs and its truth are in the site's ``units``
(``m``, ``cm``, ``mm``, ``ft``, ``in``). Tracker configs state every length, speed and area
in **metres** (m, m/s, m^2), so one ``run.toml`` means the same on a site drawn in cm and on
one drawn in m. A config field says it carries a physical unit with :func:`length` (or
``field(metadata={"unit": "m/s"})``); :func:`config_in_site_units` converts every such field
once, before the tracker runs::

    value_site = value_m * (site units per metre) ** power      (power 1 for m and m/s, 2 for m^2)

Trackers therefore compute in site units only, and their outputs (tracks, errors) are in
site units, labelled with ``site.units`` in the report.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from onebit.core.errors import SiteError
from onebit.core.params import param

#: metres per site unit
METRES_PER_UNIT: dict[str, float] = {"m": 1.0, "cm": 0.01, "mm": 0.001, "ft": 0.3048, "in": 0.0254}

#: physical unit of a config field -> power of the length scale it carries
UNIT_POWER: dict[str, int] = {"m": 1, "m/s": 1, "m^2": 2}


def length(default: Any = dataclasses.MISSING, doc: str = "", *, unit: str = "m", **kwargs) -> Any:
    """A dataclass field holding a length (or speed, area) in metres:
    ``v_max: float = length(4.0, "top walking speed", unit="m/s", lo=0.0)``. With a ``doc`` it is
    a declared parameter (:func:`onebit.core.params.param`: bounds, choices as keywords)."""
    if unit not in UNIT_POWER:
        raise ValueError(f"unit {unit!r}; expected one of {sorted(UNIT_POWER)}")
    if doc:
        return param(default, doc, unit=unit, **kwargs)
    return dataclasses.field(default=default, metadata={"unit": unit}, **kwargs)


def units_per_metre(units: str) -> float:
    """Site units in one metre (100 for ``cm``)."""
    if units not in METRES_PER_UNIT:
        raise SiteError(f"unknown unit {units!r}; expected one of {sorted(METRES_PER_UNIT)}", field="units")
    return 1.0 / METRES_PER_UNIT[units]


def to_site_units(value: Any, unit: str, site_units: str) -> Any:
    """``value`` (metres, m/s or m^2; a number, a list of numbers or ``None``) in site units."""
    if value is None:
        return None
    k = units_per_metre(site_units) ** UNIT_POWER[unit]
    if isinstance(value, (list, tuple)):
        return type(value)(v * k for v in value)
    return value * k


def config_in_site_units(config: Any, site: Any) -> Any:
    """A copy of the frozen config ``config`` with every unit-carrying field in ``site.units``.

    Fields without a length ``unit`` (m, m/s, m^2) in their metadata are unchanged; on a site in metres the
    config is returned as it is.
    """
    if not dataclasses.is_dataclass(config) or units_per_metre(site.units) == 1.0:
        return config
    changes = {
        f.name: to_site_units(getattr(config, f.name), f.metadata["unit"], site.units)
        for f in dataclasses.fields(config)
        if f.metadata.get("unit") in UNIT_POWER
    }
    return dataclasses.replace(config, **changes) if changes else config
