"""One meaning of ``targets`` for every tracker (issue 12, item 7).

``site.toml`` ``targets`` is the most targets present at once. The intruder filter serves one
(skipped when more are declared; when undeclared and the truth shows several at once, the
report says it cannot serve them instead of printing an error); istate holds ``n`` = targets,
people may come and go; beams creates at most that many agents; findinghumo reports at most
that many users at a time.
"""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from onebit.core.region_graph import build_region_graph
from onebit.core.site import load_site
from onebit.datasets.catalogue import get_scenario
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline
from onebit.trackers.beams.stage import BeamsConfig
from onebit.trackers.beams.stage import run as run_beams
from onebit.trackers.findinghumo.stage import cap_users


@pytest.fixture(scope="module")
def hallway(tmp_path_factory):
    return get_scenario("hallway").write(
        tmp_path_factory.mktemp("t") / "hall", seed=1, duration=40.0, agents=3, drop=0.0, camera=False, params={}
    )


def test_declared_targets_skip_the_single_target_filter(hallway, tmp_path):
    assert load_site(hallway / "site.toml").targets == 3  # the simulator declares what it simulated
    res = run_pipeline(hallway, tmp_path / "run", trackers=("intruder", "intruder-naive", "findinghumo"), rrd=False)
    for name in ("intruder", "intruder-naive"):
        assert res.status[name].startswith("skipped") and "3 targets" in res.status[name]
    assert metric(res.report, "findinghumo/users_decoded") <= 3


def test_undeclared_targets_the_report_says_the_filter_cannot_serve(hallway, tmp_path):
    text = (hallway / "site.toml").read_text()
    data = tmp_path / "hall"
    data.mkdir()
    for f in ("motion.csv", "truth.csv"):
        (data / f).write_bytes((hallway / f).read_bytes())
    (data / "site.toml").write_text("\n".join(ln for ln in text.splitlines() if not ln.startswith("targets")))
    res = run_pipeline(data, tmp_path / "run", trackers=("intruder",), rrd=False)
    assert res.status["intruder"].startswith("ok") and res.ok
    assert res.status["scores/intruder"].startswith("cannot serve the data: the truth has 3 targets at once")
    rows = res.report.filter(pl.col("stage") == "intruder")
    assert rows.select("metric", "value").rows() == [("cannot_serve", 1.0)]  # no error number


def test_istate_people_come_and_go(tmp_path):
    data = get_scenario("istate-room").write(
        tmp_path / "room", seed=2, duration=40.0, agents=2, drop=0.0, camera=False, params={}
    )
    truth = pl.read_csv(data / "truth.csv")
    # target2 leaves at 20 s and a third person comes in: 3 ids, never more than 2 at once
    truth = truth.with_columns(
        pl.when((pl.col("target") == "target2") & (pl.col("t") >= 20.0))
        .then(pl.lit("target3"))
        .otherwise(pl.col("target"))
        .alias("target")
    )
    truth.write_csv(data / "truth.csv")
    res = run_pipeline(data, tmp_path / "run", trackers=("istate",), rrd=False)
    assert metric(res.report, "istate/containment") == 1.0 and metric(res.report, "istate/scored_stages") >= 35
    (data / "site.toml").write_text((data / "site.toml").read_text().replace("targets = 2", "targets = 1"))
    res = run_pipeline(data, tmp_path / "run1", trackers=("istate",), rrd=False)
    assert "cannot serve the data: the truth has 2 targets" in res.status["scores/istate"]
    assert metric(res.report, "istate/containment") is None and metric(res.report, "istate/cannot_serve") == 1.0


def test_beams_creates_at_most_targets_agents(tmp_path):
    data = get_scenario("beams-lab").write(
        tmp_path / "lab", seed=7, duration=60.0, agents=2, drop=0.0, camera=False, params={}
    )
    site = load_site(data / "site.toml")
    assert site.targets == 2
    rg = build_region_graph(site)
    dec = run_pipeline(data, tmp_path / "run", trackers=("beams",), rrd=False)
    cr = pl.read_parquet(tmp_path / "run" / "tables" / "crossings.parquet")
    out = run_beams({"crossings": cr, "region_graph": rg}, site, BeamsConfig())
    assert out["agents"].height <= 2 and metric(dec.report, "beams/agents") <= 2
    one = site.__class__(**{**site.__dict__, "targets": 1})
    capped = run_beams({"crossings": cr, "region_graph": rg}, one, BeamsConfig())
    assert capped["agents"].height == 1
    if out["agents"].height == 2:  # the second agent's crossings cannot be explained by one
        assert capped["unexplained"].height > 0


def test_findinghumo_cap_keeps_the_user_that_explains_the_activity():
    hops = np.array([[0, 1, 2], [1, 0, 1], [2, 1, 0]])
    active = np.zeros((6, 3), bool)
    active[[0, 1, 2, 3, 4, 5], [0, 0, 1, 1, 2, 2]] = True  # one walker 0 -> 1 -> 2
    paths = np.array(
        [
            [0, 0, 1, 1, 1, 1],  # the walker, then left behind at 1
            [-1, -1, 2, 2, 2, 2],  # a ghost that appears at 2 (a K_now burst)
            [-1, -1, -1, -1, 2, 2],
        ]
    )
    out = cap_users(paths, active, hops, 1)
    assert out.shape == (1, 6) and out[0].tolist() == [0, 0, 1, 1, 2, 2]
    assert cap_users(paths, active, hops, 0) is paths and cap_users(paths, active, hops, 3) is paths
