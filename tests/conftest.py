"""Shared fixtures: the built-in sites with their region graphs (built once per session)."""

import os

import pytest

from onebit.core.region_graph import build_region_graph
from onebit.datasets.builtin import builtin_site

os.environ.setdefault("RERUN_ANALYTICS", "0")


@pytest.fixture(scope="session")
def building():
    """Bobadilla et al. Fig. 1: ``(site, region_graph)``."""
    site = builtin_site("building")
    return site, build_region_graph(site)


@pytest.fixture(scope="session")
def lab():
    """Bobadilla et al. Fig. 8, the lab: ``(site, region_graph)``."""
    site = builtin_site("lab")
    return site, build_region_graph(site)
