"""The small studies on every executor, for ``test_executors.py`` (the seed sweeps, with Ray) and
``test_executors_trials.py`` (the trial studies, without Ray): two files, so that under
``pytest -n --dist loadfile`` the studies are shared by both workers, and one of them starts Ray."""

from __future__ import annotations

import polars as pl
import pytest

from onebit.experiments import get_experiment
from onebit.pipeline.executors import LocalPoolExecutor, RayExecutor, SerialExecutor


@pytest.fixture(scope="module")
def studies(tmp_path_factory, request):
    """The module's ``STUDIES`` ((study, trials) pairs, each study's `quick` grid) on the serial
    executor and a local process pool, and its ``RAY_STUDIES`` on Ray as well (the session's
    ``ray_local``): {(study, executor): output folder}."""
    wanted, on_ray = request.module.STUDIES, request.module.RAY_STUDIES
    executors = {"serial": SerialExecutor(), "local": LocalPoolExecutor(workers=2)}
    if on_ray:
        request.getfixturevalue("ray_local")
        executors["ray"] = RayExecutor(workers=2)
    root = tmp_path_factory.mktemp("studies")
    outs = {}
    for kind, ex in executors.items():
        with ex:
            for name, trials in wanted:
                if kind == "ray" and name not in on_ray:
                    continue
                outs[(name, kind)] = get_experiment(name).run(
                    root / f"{name}-{kind}", seed=0, trials=trials, quick=True, echo=lambda s: None, executor=ex
                )
    return outs


@pytest.fixture
def equal_tables(studies, request):
    """``check(name)``: the study's tables (results, and the summary when it writes one) on the
    local pool (and Ray, for the module's ``RAY_STUDIES``) equal the serial run's; the timings
    have one row per trial on each."""

    def check(name: str) -> None:
        serial = studies[(name, "serial")]
        tables = ["results.parquet", *(["summary.csv"] if (serial / "summary.csv").exists() else [])]
        for kind in ("local", "ray") if name in request.module.RAY_STUDIES else ("local",):
            other = studies[(name, kind)]
            for t in tables:
                read = pl.read_parquet if t.endswith(".parquet") else pl.read_csv
                a, b = read(serial / t), read(other / t)
                assert a.height > 0 and a.equals(b), (name, kind, t)
            timings = pl.read_csv(other / "timings.csv")
            assert timings.height == pl.read_csv(serial / "timings.csv").height and (timings["seconds"] >= 0).all()

    return check
