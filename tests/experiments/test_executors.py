"""The executors keep the items' order, report failing tasks, give a pool worker's stages one
core; the seed sweeps on serial, a local process pool and Ray give equal tables (the trial
studies: test_executors_trials.py, which needs no Ray); the CLI takes the options."""

from __future__ import annotations

import math
import os

import polars as pl
import pytest

from onebit.cli import main
from onebit.experiments import EXPERIMENTS
from onebit.experiments.trials import StudyError, run_trials
from onebit.pipeline.executors import LocalPoolExecutor, RayExecutor, SerialExecutor

ray = pytest.importorskip("ray", reason="the ray extra (pip install 'onebit[ray]'; make test installs it)")

#: (study, trials) small enough for a test; each study's own `quick` grid otherwise (the studies
#: fixture, tests/experiments/conftest.py; the trial studies: test_executors_trials.py)
STUDIES = (("correct", 2), ("findinghumo", 2))
#: the study also run on Ray (its tasks are pickled more leniently than the local pool's, which
#: runs every study: a trial function the pool can take, Ray can take): a seed sweep with its summary
RAY_STUDIES = ("correct",)


def _executors():
    return {"serial": SerialExecutor(), "local": LocalPoolExecutor(workers=2), "ray": RayExecutor(workers=2)}


@pytest.mark.parametrize("kind", ["serial", "local", "ray"])
def test_map_keeps_the_order_and_reports_a_failing_task_without_stopping(kind, ray_local):
    with _executors()[kind] as ex:
        out = ex.map(math.sqrt, [16.0, -1.0, 9.0, 4.0])
        assert ex.map(math.sqrt, []) == []  # a second map on the same executor (Ray: connected once)
    assert [o.index for o in out] == [0, 1, 2, 3]
    assert [o.value for o in out] == [4.0, None, 3.0, 2.0]
    assert [o.ok for o in out] == [True, False, True, True]
    assert out[1].error == "ValueError: math domain error" and "Traceback" in out[1].traceback


def _cores_here(_: int) -> int:
    from onebit.core.parallel import available_cores

    return available_cores()


@pytest.mark.parametrize("kind", ["local", "ray"])
def test_a_pool_worker_gives_its_stages_one_core(kind, ray_local, monkeypatch):
    """Every core already runs a task of the pool: a stage inside one (clustertrack's runs) does
    not start workers of its own (``ONEBIT_CORES=1`` in the worker)."""
    monkeypatch.delenv("ONEBIT_CORES", raising=False)
    with _executors()[kind] as ex:
        out = ex.map(_cores_here, [0, 1])
    assert [o.value for o in out] == [1, 1]
    assert "ONEBIT_CORES" not in os.environ  # this process is not a worker


def test_a_failed_trial_fails_the_study_naming_it():
    with pytest.raises(StudyError, match=r"1 of 3 trial\(s\) failed:\n  x = -1.0: ValueError: math domain error"):
        run_trials(
            math.sqrt, [1.0, -1.0, 4.0], executor=None, label=lambda x: f"x = {x}", echo=lambda s: None, study="t"
        )
    values, timings = run_trials(math.sqrt, [1.0, 4.0], executor=None, label=str, echo=lambda s: None, study="t")
    assert values == [1.0, 2.0] and timings["trial"].to_list() == ["1.0", "4.0"]


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


def test_cli_experiment_takes_the_executor_options(tmp_path, capsys):
    """The experiment command takes the executor options (on schiff, the quickest study on a pool)."""
    assert (
        main(
            [
                "experiment",
                "schiff",
                str(tmp_path / "ok"),
                "--quick",
                "--trials",
                "1",
                "--executor",
                "local",
                "--workers",
                "2",
            ]
        )
        == 0
    )
    assert "local process pool, 2 worker(s)" in capsys.readouterr().out
    assert pl.read_parquet(tmp_path / "ok" / "results.parquet").height == 5
    assert main(["experiment", "okane", str(tmp_path / "x"), "--quick", "--ray-address", "auto"]) == 2
    assert "--ray-address: only with --executor ray" in capsys.readouterr().err
