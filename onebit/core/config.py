"""Config constraint helpers: every stage config is a frozen keyword-only dataclass whose
``__post_init__`` checks its fields with these; the error names the class, the field, the value
and what is allowed (:class:`~onebit.core.errors.ConfigError`)."""

from __future__ import annotations

from dataclasses import fields
from typing import Any

from onebit.core.errors import ConfigError


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
    value = getattr(obj, name)
    ok = isinstance(value, types) and not isinstance(value, bool)
    ok = ok and (lo is None or value >= lo) and (hi is None or value <= hi)
    if not ok:
        raise ConfigError(f"{type(obj).__name__}.{name} = {value!r}; allowed range: [{lo}, {hi}]")
