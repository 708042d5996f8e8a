"""Shared fixtures (each made once per session, so once per worker under `pytest -n`): the built-in
sites with their region graphs, and one local Ray instance for every test that uses Ray."""

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


@pytest.fixture(scope="session")
def ray_local():
    """One small local Ray instance for every test that uses Ray (2 CPUs, no dashboard, no
    usage stats), started by the first of them and shut down when the session ends: starting
    Ray takes seconds, so the Ray tests of every module share one. Skips without the ray extra."""
    ray = pytest.importorskip("ray", reason="the ray extra (pip install 'onebit[ray]'; make test installs it)")
    os.environ["RAY_USAGE_STATS_ENABLED"] = "0"
    ray.init(
        address="local",
        num_cpus=2,
        include_dashboard=False,
        object_store_memory=100 * 1024**2,
        log_to_driver=False,
        logging_level="ERROR",
    )
    yield ray
    ray.shutdown()
