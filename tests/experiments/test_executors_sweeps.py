"""The seed sweeps on every executor: serial, a local process pool and Ray give equal tables
(the executors themselves and the trial studies: test_executors.py)."""

from __future__ import annotations

import polars as pl
import pytest

from onebit.experiments import EXPERIMENTS

pytest.importorskip("ray", reason="the ray extra (pip install 'onebit[ray]'; make test installs it)")

#: (study, trials) small enough for a test; each study's own `quick` grid otherwise (the studies
#: fixture, tests/experiments/conftest.py)
STUDIES = (("correct", 2), ("findinghumo", 2))
#: the study also run on Ray (its tasks are pickled more leniently than the local pool's, which
#: runs every study: a trial function the pool can take, Ray can take): a seed sweep with its summary
RAY_STUDIES = ("correct",)


@pytest.mark.parametrize("name", [s for s, _ in STUDIES])
def test_serial_local_pool_and_ray_give_equal_tables(equal_tables, name):
    equal_tables(name)


def test_the_seed_sweeps_are_experiments(studies):
    assert {"correct", "findinghumo"} <= set(EXPERIMENTS)
    fh = pl.read_parquet(studies[("findinghumo", "serial")] / "results.parquet")
    assert fh.height == 2 * 4 and set(fh["tracker"]) == {"findinghumo", "findinghumo-flow", "hmm1", "hmm2"}
    assert (fh["users_true"] == 3).all() and (fh["hop_error"] >= 0).all()
    corr = pl.read_parquet(studies[("correct", "serial")] / "results.parquet")
    assert corr["seed"].to_list() == [0, 1]
    assert ((corr["restored"] <= corr["dropped"]) & (corr["restored"] <= corr["inserted"])).all()
    summary = pl.read_csv(studies[("correct", "serial")] / "summary.csv")
    assert summary["seeds"][0] == 2
