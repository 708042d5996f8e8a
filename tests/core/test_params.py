"""Parameters declared once (onebit.core.params): the helper itself, and one contract test over
every declared config that probes every declared bound and choice -- just inside accepted, just
outside refused with an error naming the field."""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import pytest

from onebit.core.errors import ConfigError
from onebit.core.params import derived, describe, kernel_tuple, param, validate
from onebit.core.units import config_in_site_units, length
from onebit.pipeline.check import SuspectConfig
from onebit.pipeline.config_show import config_sections
from onebit.trackers.binpf.config import FilterParams


@dataclasses.dataclass(frozen=True, kw_only=True)
class Toy:
    """A toy config."""

    n: int = param(3, "a count", lo=1, hi=10)
    x: float = length(0.5, "a length", lo=0.0, hi="y")
    y: float = param(2.0, "an upper bound of x", lo=("n", -3))
    mode: str = param("a", "a mode", choices=("a", "b"))
    on: bool = param(True, "a switch")
    maybe: float | None = param(None, "unset or positive", lo=1e-9, unit="s")
    table: dict = param(doc="a table, checked by the config's own code", factory=dict)

    def __post_init__(self) -> None:
        validate(self)


def test_a_declaration_gives_default_doc_bounds_and_unit():
    info = {p.name: p for p in describe(Toy)}
    assert Toy().n == 3 and Toy().table == {}
    assert (info["n"].kind, info["n"].lo, info["n"].hi, info["n"].allowed()) == ("int", 1, 10, "[1, 10]")
    assert info["x"].unit == "m" and info["x"].allowed() == "[0.0, y]"
    assert info["y"].allowed() == ">= n + -3"
    assert info["mode"].allowed() == '"a" | "b"'
    assert info["maybe"].optional and info["maybe"].unit == "s" and not info["n"].optional
    assert info["table"].kind == "dict" and info["table"].default == {}


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"n": 0}, r"Toy\.n = 0; allowed range: \[1, 10\] \(an integer\)"),
        ({"n": 2.0}, r"Toy\.n = 2\.0; allowed range"),
        ({"n": True}, r"Toy\.n = True"),
        ({"x": 3.0}, r"Toy\.x = 3\.0; allowed range: \[0\.0, 2\.0\]"),  # hi = y's value
        ({"x": math.nan}, r"Toy\.x = nan; allowed range"),
        ({"n": 5, "y": 1.5}, r"Toy\.y = 1\.5; allowed range: \[2, None\]"),  # lo = n - 3
        ({"mode": "c"}, r"Toy\.mode = 'c'; allowed values: \['a', 'b'\]"),
        ({"on": 1}, r"Toy\.on = 1; must be true or false"),
        ({"maybe": 0.0}, r"Toy\.maybe = 0\.0; allowed range"),
        ({"n": None}, r"Toy\.n = None; a value is required"),
    ],
)
def test_validation_names_the_field_the_value_and_what_is_allowed(kwargs, message):
    with pytest.raises(ConfigError, match=message):
        Toy(**kwargs)


def test_only_length_units_are_converted_to_site_units():
    site = type("S", (), {"units": "cm"})()
    got = config_in_site_units(Toy(maybe=2.0, y=100.0), site)
    assert got.x == 50.0 and got.maybe == 2.0 and got.y == 100.0  # x in m -> cm; seconds unchanged


def test_a_parameter_without_a_doc_or_with_an_unknown_unit_is_refused():
    with pytest.raises(ValueError, match="doc"):
        param(1)
    with pytest.raises(ValueError, match="unit"):
        param(1, "a count", unit="furlongs")


def test_derived_takes_the_declarations_and_validates():
    D = derived(
        "D", Toy, ("n", "mode"), defaults={"n": 4}, extra={"k": param(0, "extra", lo=0)}, doc="D.", module=__name__
    )
    assert D().n == 4 and D().k == 0 and dataclasses.fields(D)[0].metadata["doc"] == "a count"
    with pytest.raises(ConfigError, match=r"D\.n = 11"):
        D(n=11)
    with pytest.raises(ConfigError, match=r"D\.k = -1"):
        D(k=-1)


def test_kernel_tuple_converts_to_the_declared_kinds():
    class K(NamedTuple):
        a: float
        b: int

    k = kernel_tuple(K, a=1, b=2.0)
    assert type(k.a) is float and type(k.b) is int and k == (1.0, 2)


def test_binpf_filter_params_are_the_configs_declarations():
    from onebit.trackers.binpf.config import FILTER_FIELDS, BinPFConfig

    cfg = {f.name: f for f in dataclasses.fields(BinPFConfig)}
    for f in dataclasses.fields(FilterParams):
        if f.name in FILTER_FIELDS:
            assert f.metadata == cfg[f.name].metadata
            assert f.default == (12 if f.name == "max_tracks" else cfg[f.name].default)


# --------------------------------------------------------------------------- the contract over every config

#: Other fields a choice needs to be accepted (the configs' explicit cross-field checks).
COMPANIONS = {
    ("eatg", "file"): {"eatg_file": "eatg.parquet"},
    ("decoding", "lagged"): {"eatg": "layout"},
}

CONFIGS = {**config_sections(), "binpf FilterParams": FilterParams, "check SuspectConfig": SuspectConfig}


def _probes(cls):
    """``(field, value, accepted, companions)`` for every declared bound and choice of ``cls``."""
    base = cls()
    for p in describe(cls):
        needs: dict = {}  # a bound on an unset field (end >= start): set that field first
        if p.choices is not None:
            for c in p.choices:
                yield p.name, c, True, COMPANIONS.get((p.name, c), {})
            yield p.name, ("not-a-choice" if isinstance(p.choices[0], str) else -12345), False, {}
        for side, bound in (("lo", p.lo), ("hi", p.hi)):
            if bound is None:
                continue
            ref = bound if isinstance(bound, str) else bound[0] if isinstance(bound, tuple) else None
            if ref is not None and getattr(base, ref) is None:
                needs = {ref: 0.0}
            if ref is None:
                v = bound
            else:
                v = needs.get(ref, getattr(base, ref)) + (bound[1] if isinstance(bound, tuple) else 0)
            if p.kind == "int":
                out = v - 1 if side == "lo" else v + 1
            else:
                out = math.nextafter(v, -math.inf if side == "lo" else math.inf)
            yield p.name, v, True, needs
            yield p.name, out, False, needs
        if p.kind in ("int", "float"):
            yield p.name, "1", False, {}  # a string is never a number
        if p.kind == "bool":
            yield p.name, 1, False, {}


def _dependents(cls, name: str) -> set[str]:
    """Fields whose declared bound is ``name``'s value."""
    return {p.name for p in describe(cls) for b in (p.lo, p.hi) if b == name or (isinstance(b, tuple) and b[0] == name)}


@pytest.mark.parametrize("section", sorted(CONFIGS))
def test_every_declared_bound_and_choice_holds(section):
    cls = CONFIGS[section]
    assert describe(cls), f"{cls.__name__} declares no parameter"
    for field, value, accepted, companions in _probes(cls):
        kwargs = {field: value, **companions}
        if accepted:
            try:
                cls(**kwargs)
            except ConfigError as exc:  # only a field whose bound is this one's value may object
                named = {d for d in _dependents(cls, field) if f".{d} = " in str(exc)}
                assert named, f"{cls.__name__}({kwargs}) refused: {exc}"
        else:
            with pytest.raises(ConfigError, match=rf"{cls.__name__}\.{field} = "):
                cls(**kwargs)


@pytest.mark.parametrize("section", sorted(CONFIGS))
def test_every_field_is_declared_with_a_doc(section):
    cls = CONFIGS[section]
    undeclared = [f.name for f in dataclasses.fields(cls) if "doc" not in f.metadata]
    assert not undeclared, f"{cls.__name__}: fields without a param declaration: {undeclared}"
    assert cls() == cls(**{p.name: p.default for p in describe(cls)})
