"""Config constraint helpers. Every stage config is a frozen keyword-only dataclass whose fields
are declared with :func:`onebit.core.params.param` (default, doc, bounds, choices, unit) and
whose ``__post_init__`` checks them with :func:`onebit.core.params.validate`; the error names
the class, the field, the value and what is allowed (:class:`~onebit.core.errors.ConfigError`).
:func:`check_range` and :func:`check_choice` check one value by hand (the simulators' options);
the allocation limits below bound what a config may make a tracker allocate."""

from __future__ import annotations

import math
import tomllib
from dataclasses import fields
from pathlib import Path
from typing import Any

from onebit.core.errors import ConfigError, InputError

#: Bounds on what a config value (or a value derived from one and the data) may make the trackers
#: allocate; past one a run is refused with a :class:`ConfigError` naming the field, never left to
#: exhaust memory. A table of this many rows is about 1 GB or less.
#:
#: slots x sensors of a frames table (a ``period`` too short for the logs' span, ``instants``)
MAX_FRAME_CELLS = 20_000_000
#: time steps a tracker or reader is cut into: instants, stages, iterations, rows per person
MAX_STEPS = 10_000_000
#: cells of a world grid or raster, times the sensors when each sensor has a map over it
MAX_GRID_CELLS = 20_000_000
#: particles of a particle filter, over all its tracks
MAX_PARTICLES = 10_000_000
#: agents, people or targets a config may declare
MAX_TARGETS = 10_000


def check_size(count: float, limit: int, *, what: str, field: str, hint: str = "") -> None:
    """Refuse an allocation of ``count`` ``what`` sized by the config value ``field`` (e.g.
    ``"[proximity] instants"``) when it is over ``limit``: a :class:`ConfigError` naming both."""
    if not count <= limit:  # also NaN
        c = f"{count:,.0f}" if math.isfinite(count) else repr(count)
        raise ConfigError(f"{field}: {c} {what}, more than the {limit:,} onebit allows{'; ' + hint if hint else ''}")


def config_from_mapping(cls: type, values: dict[str, Any] | None, *, section: str):
    """Build a config dataclass from a ``run.toml`` section, naming unknown fields."""
    values = dict(values or {})
    known = {f.name for f in fields(cls)}
    for k in values:
        if k not in known:
            raise ConfigError(f"[{section}] unknown field '{k}'; known fields: {sorted(known)}")
    return cls(**values)


def check_choice(obj, name: str, allowed: tuple) -> None:
    value = getattr(obj, name)
    if value not in allowed:
        raise ConfigError(f"{type(obj).__name__}.{name} = {value!r}; allowed values: {list(allowed)}")


def check_range(obj, name: str, lo=None, hi=None, *, types=(int, float)) -> None:
    """``obj.name`` is a number of ``types`` (never a bool), finite, in ``[lo, hi]``."""
    value = getattr(obj, name)
    ok = isinstance(value, types) and not isinstance(value, bool)
    ok = ok and (not isinstance(value, float) or math.isfinite(value))
    ok = ok and (lo is None or value >= lo) and (hi is None or value <= hi)
    if not ok:
        raise ConfigError(f"{type(obj).__name__}.{name} = {value!r}; allowed range: [{lo}, {hi}]")


def load_toml(path: str | Path, *, error: type[InputError] = InputError) -> dict[str, Any]:
    """Parse a user's TOML file (``site.toml``, ``run.toml``); every problem is an ``error``
    (an :class:`InputError` subclass) naming the file and, where known, the line: unreadable,
    not UTF-8 (the byte, line and column), not TOML, or nested too deeply to parse."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise error(f"cannot read: {exc.strerror or exc}", file=path) from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        col = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        raise error(f"not UTF-8 text: byte 0x{data[exc.start]:02X} at column {col}", file=path, line=line) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"not valid TOML: {exc}", file=path) from None
    except RecursionError:
        raise error("not valid TOML here: arrays or tables nested too deeply to read", file=path) from None
