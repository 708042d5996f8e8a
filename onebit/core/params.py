"""Parameters declared once: every field of a stage config says its default, doc, bounds,
choices and unit in one :func:`param` (or :func:`~onebit.core.units.length` for a length,
speed or area in metres), and everything else is read from that declaration:

- :func:`validate` checks an instance (a config's ``__post_init__`` calls it first; checks that
  tie several fields together stay explicit code after it), each error a
  :class:`~onebit.core.errors.ConfigError` naming the class, the field, the value and what is
  allowed;
- :func:`describe` lists the parameters of a config class, for ``onebit config show``
  (:mod:`onebit.pipeline.config_show`) and the generated reference ``docs/parameters.md``
  (``tools/params_md.py``);
- :func:`kernel_tuple` builds a compiled kernel's parameter tuple (a ``NamedTuple``) from named
  values, each converted to the declared kind.

A declaration, in a frozen keyword-only dataclass::

    particles: int = param(300, "particles per track", lo=1, hi=10**6)
    edge: float = length(0.3, "width of the footprint's soft edge", lo=0.0, hi=1e6)
    policy: str = param("fifo", "queue discipline", choices=("fifo", "lifo"))
    r_out: float = param(0.65, "reported while existence is at least this", lo="r_delete", hi=1.0)

A bound is a number, the name of another field of the same config (its value is the bound), or
``(field, offset)`` (that field's value plus the offset).
The field's kind (``int``, ``float``, ``bool``, ``str``, optional with ``| None``) is read from
its annotation: an ``int`` must be an integer, a ``float`` a finite number (an integer too),
never a bool; a ``bool`` must be true or false; a ``str`` a string; ``None`` is allowed only by
``| None``. Other kinds (tables, lists) are checked by the config's own code.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Callable
from typing import Any, NamedTuple

from onebit.core.errors import ConfigError

#: Units a parameter may state (the first three are converted to the site's units,
#: :mod:`onebit.core.units`; the others are documentary).
UNITS = ("m", "m/s", "m^2", "s", "Hz", "slots", "frames", "nats", "cells", "cells/s", "deg")

#: A bound: a number, another field's name, or ``(field, offset)`` (the field's value plus the offset).
Bound = float | str | tuple[str, float] | None


def param(
    default: Any = dataclasses.MISSING,
    doc: str = "",
    *,
    lo: Bound = None,
    hi: Bound = None,
    choices: tuple | None = None,
    unit: str | None = None,
    factory: Callable[[], Any] | None = None,
) -> Any:
    """A dataclass field declared as a parameter (module docstring): ``default`` (or
    ``factory`` for a table or list), a one-line ``doc``, inclusive bounds ``lo``/``hi`` (a
    number, another field's name or ``(field, offset)``), allowed ``choices`` and the ``unit``."""
    if not doc:
        raise ValueError("param: every parameter needs its doc")
    if unit is not None and unit not in UNITS:
        raise ValueError(f"param: unit {unit!r}; expected one of {list(UNITS)}")
    meta: dict[str, Any] = {"doc": doc, "lo": lo, "hi": hi, "choices": tuple(choices) if choices else None}
    if unit is not None:
        meta["unit"] = unit
    if factory is not None:
        return dataclasses.field(default_factory=factory, metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


@dataclasses.dataclass(frozen=True)
class ParamInfo:
    """One declared parameter of a config class (what :func:`describe` gives)."""

    name: str
    default: Any
    kind: str  #: "int", "float", "bool", "str" or the annotation's text (a table, a list)
    optional: bool  #: ``None`` is allowed
    doc: str
    lo: Bound
    hi: Bound
    choices: tuple | None
    unit: str | None

    def allowed(self) -> str:
        """What values are allowed, in words: ``[0.0, 1.0]``, ``>= 1``, ``"fifo" | "lifo"``, ...;
        empty when the declaration says nothing beyond the kind."""
        if self.choices is not None:
            return " | ".join(json.dumps(c) for c in self.choices)  # as TOML writes them
        if self.lo is not None and self.hi is not None:
            return f"[{_show(self.lo)}, {_show(self.hi)}]"
        if self.lo is not None:
            return f">= {_show(self.lo)}"
        if self.hi is not None:
            return f"<= {_show(self.hi)}"
        return ""


def _show(v: Any) -> str:
    if isinstance(v, tuple) and len(v) == 2 and isinstance(v[0], str):  # a bound: a field plus an offset
        return f"{v[0]} + {v[1]!r}"
    if isinstance(v, str):
        return v if v.isidentifier() and not v.startswith(("'", '"')) else repr(v)
    return repr(v)


def _kind(annotation: Any) -> tuple[str, bool]:
    """``(kind, optional)`` of a field annotation (a string under ``from __future__ import annotations``)."""
    text = getattr(annotation, "__forward_arg__", annotation)  # a NamedTuple's string annotation
    text = text if isinstance(text, str) else getattr(text, "__name__", str(text))
    parts = [p.strip() for p in text.split("|")]
    optional = "None" in parts
    rest = [p for p in parts if p != "None"]
    return (rest[0] if len(rest) == 1 else text), optional


def declared(cls_or_obj: Any) -> list[dataclasses.Field]:
    """The fields of a config declared with :func:`param` (in declaration order)."""
    return [f for f in dataclasses.fields(cls_or_obj) if "doc" in f.metadata]


def describe(cls: type) -> list[ParamInfo]:
    """Every declared parameter of the config class ``cls``, in declaration order."""
    out = []
    for f in declared(cls):
        kind, optional = _kind(f.type)
        if f.default is not dataclasses.MISSING:
            default = f.default
        elif f.default_factory is not dataclasses.MISSING:
            default = f.default_factory()
        else:
            default = dataclasses.MISSING
        m = f.metadata
        out.append(ParamInfo(f.name, default, kind, optional, m["doc"], m["lo"], m["hi"], m["choices"], m.get("unit")))
    return out


def bound_value(obj: Any, bound: Bound) -> Any:
    """A bound's value on ``obj``: the number itself, the value of the field it names, or that
    value plus an offset (``("d_max", 10)``)."""
    if isinstance(bound, tuple):
        return getattr(obj, bound[0]) + bound[1]
    return getattr(obj, bound) if isinstance(bound, str) else bound


def _is_number(v: Any, kind: str) -> bool:
    if isinstance(v, bool):
        return False
    if kind == "int":
        return isinstance(v, int)
    return isinstance(v, (int, float)) and (not isinstance(v, float) or math.isfinite(v))


def check_field(obj: Any, f: dataclasses.Field) -> None:
    """Check one declared field of ``obj`` against its declaration (:func:`validate`)."""
    name, m = f.name, f.metadata
    kind, optional = _kind(f.type)
    value = getattr(obj, name)
    where = f"{type(obj).__name__}.{name} = {value!r}"
    if value is None:
        if optional:
            return
        raise ConfigError(f"{where}; a value is required")
    if kind == "bool" and not isinstance(value, bool):
        raise ConfigError(f"{where}; must be true or false")
    if m["choices"] is not None:
        if value not in m["choices"] or isinstance(value, bool) != isinstance(m["choices"][0], bool):
            raise ConfigError(f"{where}; allowed values: {list(m['choices'])}")
        return
    if kind == "str" and not isinstance(value, str):
        raise ConfigError(f"{where}; must be a string")
    if kind in ("int", "float"):
        lo, hi = bound_value(obj, m["lo"]), bound_value(obj, m["hi"])
        ok = _is_number(value, kind) and (lo is None or value >= lo) and (hi is None or value <= hi)
        if not ok:
            what = "an integer" if kind == "int" else "a finite number"
            raise ConfigError(f"{where}; allowed range: [{lo}, {hi}] ({what})")


def validate(obj: Any) -> None:
    """Check every declared field of the config ``obj`` (module docstring); the first bad one
    raises a :class:`ConfigError` naming it."""
    for f in declared(obj):
        check_field(obj, f)


def derived(
    name: str,
    cls: type,
    names: tuple[str, ...],
    *,
    defaults: dict[str, Any] | None = None,
    extra: dict[str, Any] | None = None,
    doc: str,
    module: str,
) -> type:
    """A frozen keyword-only dataclass ``name`` whose fields are the declarations ``names`` of the
    config class ``cls`` (type, default, doc, bounds, unit: not copied by hand), with
    ``defaults`` replacing some defaults, then the ``extra`` declarations (``{name: param(...)}``
    of ``float`` unless the default is an ``int`` or ``bool``). It validates itself as ``cls``
    does (:func:`validate`); a bound naming a field of ``cls`` must name one of ``names``."""
    defaults = defaults or {}
    by_name = {f.name: f for f in declared(cls)}
    spec = []
    for n in names:
        f = by_name[n]
        default = defaults.get(n, f.default)
        spec.append((n, f.type, dataclasses.field(default=default, metadata=f.metadata)))
    for n, fld in (extra or {}).items():
        kind = type(fld.default).__name__ if isinstance(fld.default, (bool, int, str)) else "float"
        spec.append((n, kind, fld))
    out = dataclasses.make_dataclass(
        name, spec, frozen=True, kw_only=True, namespace={"__doc__": doc, "__post_init__": validate}
    )
    out.__module__ = module
    return out


def kernel_tuple(cls: type[NamedTuple], **values: Any) -> NamedTuple:
    """An instance of the ``NamedTuple`` class ``cls`` (a compiled kernel's parameters), every
    value converted to its annotated ``float`` or ``int`` (so the kernel is compiled once and
    computes with exactly the float64 / int64 values the config gave)."""
    conv = {"float": float, "int": int, "bool": bool}
    hints = cls.__annotations__
    return cls(**{k: conv.get(_kind(hints[k])[0], lambda v: v)(v) for k, v in values.items()})
