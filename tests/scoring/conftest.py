"""Fixtures of the scoring tests: the built-in hallway site and small simulated datasets."""

from __future__ import annotations

import polars as pl
import pytest

from onebit.core.region_graph import build_region_graph
from onebit.core.site import load_site
from onebit.core.tables import TRUTH, conform
from onebit.datasets.builtin import builtin_site
from onebit.datasets.catalogue import get_scenario

#: the scenario each tracker runs on in the demo (``Makefile``), short
SCENARIOS = {
    "beams-lab": 20.0,
    "pir14": 20.0,
    "proximity-line": None,
    "proximity-grid": None,
    "hallway": 20.0,
    "istate-room": 20.0,
}


@pytest.fixture(scope="session")
def hallway_site():
    """De et al.'s hallway with its 1-hop sensor graph."""
    return builtin_site("hallway")


@pytest.fixture(scope="session")
def scenario_sites(tmp_path_factory) -> dict[str, tuple]:
    """``{scenario: (site, region_graph, truth)}`` of small simulated datasets (seed 3)."""
    root = tmp_path_factory.mktemp("scoring-sites")
    out = {}
    for name, duration in SCENARIOS.items():
        data = get_scenario(name).write(
            root / name, seed=3, duration=duration, agents=None, drop=0.0, camera=False, params={}
        )
        site = load_site(data / "site.toml")
        truth = conform(pl.read_csv(data / "truth.csv").select("t", pl.col("target").cast(pl.String), "x", "y"), TRUTH)
        out[name] = (site, build_region_graph(site), truth)
    return out
