"""Config lengths meet the site's units in one place (onebit.core.units)."""

from __future__ import annotations

import dataclasses

import pytest
from hypothesis import given
from hypothesis import strategies as st

from onebit.core.errors import ConfigError, SiteError
from onebit.core.units import METRES_PER_UNIT, config_in_site_units, length, to_site_units, units_per_metre


@dataclasses.dataclass(frozen=True, kw_only=True)
class Cfg:
    cell: float = length(1.0)
    speed: float = length(1.5, unit="m/s")
    area: float = length(2.0, unit="m^2")
    where: list | None = length(None)
    seconds: float = 3.0
    count: int = 4

    def __post_init__(self) -> None:
        if self.cell <= 0:
            raise ConfigError(f"Cfg.cell = {self.cell!r}; allowed range: (0, None]")


class Site:
    def __init__(self, units: str) -> None:
        self.units = units


def test_units_per_metre():
    assert units_per_metre("m") == 1.0
    assert units_per_metre("cm") == pytest.approx(100.0)
    assert units_per_metre("mm") == pytest.approx(1000.0)
    assert units_per_metre("ft") == pytest.approx(1 / 0.3048)
    assert units_per_metre("in") == pytest.approx(1 / 0.0254)
    with pytest.raises(SiteError, match="field 'units'.*parsec"):
        units_per_metre("parsec")


def test_metre_site_keeps_the_config_object():
    cfg = Cfg()
    assert config_in_site_units(cfg, Site("m")) is cfg


def test_cm_site_converts_lengths_speeds_and_areas_only():
    cfg = config_in_site_units(Cfg(where=[1.0, 2.0, 0.5]), Site("cm"))
    assert cfg.cell == pytest.approx(100.0)
    assert cfg.speed == pytest.approx(150.0)
    assert cfg.area == pytest.approx(2.0e4)
    assert cfg.where == pytest.approx([100.0, 200.0, 50.0]) and isinstance(cfg.where, list)
    assert (cfg.seconds, cfg.count) == (3.0, 4)


def test_none_stays_none():
    assert config_in_site_units(Cfg(), Site("ft")).where is None
    assert to_site_units(None, "m", "cm") is None


def test_unknown_site_units_are_an_error_naming_units():
    with pytest.raises(SiteError, match="units"):
        config_in_site_units(Cfg(), Site("parsec"))


def test_length_field_names_a_known_unit():
    with pytest.raises(ValueError, match="furlong"):
        length(1.0, unit="furlong")


@given(
    units=st.sampled_from(sorted(METRES_PER_UNIT)),
    v=st.floats(1e-6, 1e6, allow_nan=False, allow_infinity=False),
)
def test_conversion_is_the_inverse_of_the_site_scale(units, v):
    """A length converted to site units, measured back in metres, is the same length."""
    assert to_site_units(v, "m", units) * METRES_PER_UNIT[units] == pytest.approx(v, rel=1e-12)
    assert to_site_units(v, "m^2", units) * METRES_PER_UNIT[units] ** 2 == pytest.approx(v, rel=1e-12)
