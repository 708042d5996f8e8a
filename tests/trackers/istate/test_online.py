"""The istate filter online (onebit/trackers/istate/online.py): readings fed up to random cut
times, stage by stage, give the batch stage's tracks row for row -- silent stretches dropped
the same way -- on motion, and on proximity with a beam's crossings."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from onebit.core.errors import ConfigError
from onebit.core.site import load_site, site_from_dict
from onebit.datasets.okane_sim import write_room_dataset
from onebit.trackers.istate import online
from onebit.trackers.istate.stage import IStateConfig, run


def _online(site, cfg, inputs: dict, cuts) -> pl.DataFrame:
    state = online.start(site, cfg)
    parts = []
    for u in cuts:  # each table as the readers have emitted it by then: its rows at or before u
        seen = {k: df.filter(pl.col("t") <= u) for k, df in inputs.items()}
        parts.append(online.advance(state, seen, until=u, final=False))
    parts.append(online.advance(state, inputs, until=np.inf, final=True))
    return pl.concat(parts)


def _same(a: pl.DataFrame, b: pl.DataFrame) -> bool:
    key = ["track", "t"]
    return a.sort(key, maintain_order=True).equals(b.select(a.columns).sort(key, maintain_order=True))


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    data = write_room_dataset(tmp_path_factory.mktemp("room") / "d", seed=3, duration=40.0, n=2, drop=0.0)
    raw = pl.read_csv(data / "motion.csv")
    motion = raw.select(pl.col("t").cast(pl.Float64), "sensor", on=pl.col("value") == 1).sort("t", maintain_order=True)
    return load_site(data / "site.toml"), motion


@pytest.mark.parametrize("seed", [0, 1])
def test_fed_at_random_cuts_equals_the_batch_stage(room, seed):
    site, motion = room
    cfg = IStateConfig(latency_auto=False, latency_s=0.2, absent_after=2.0, max_elements=4)
    batch = run({"motion": motion}, site, cfg)
    stages = batch["summary"].height
    assert batch["tracks"]["t"].n_unique() < stages  # some stages are silent: their rows dropped
    cuts = np.sort(np.random.default_rng(seed).uniform(-1.0, 41.0, 12))
    assert _same(_online(site, cfg, {"motion": motion}, cuts), batch["tracks"])


def test_proximity_and_crossings_online():
    site = site_from_dict(
        {
            "boundary": {"polygon": [[0, 0], [20, 0], [20, 4], [0, 4]]},
            "beams": [{"id": "b", "segment": [[10, 0], [10, 4]], "forward": "left", "spacing": 0.1}],
            "proximity_sensors": [{"id": "p1", "position": [4, 2], "radius": 1.5}],
            "targets": 1,
        }
    )
    prox = pl.DataFrame({"t": [2.0, 5.5, 14.0], "sensor": ["p1", "p1", "p1"], "on": [True, False, True]})
    cross = pl.DataFrame({"t": [10.0, 12.3]}, schema={"t": pl.Float64}).with_columns(
        beam=pl.lit("b"), direction=pl.lit(1, pl.Int8)
    )
    cfg = IStateConfig(max_speed=1.0, latency_auto=False)
    inputs = {"proximity": prox, "crossings": cross}
    batch = run(inputs, site, cfg)["tracks"]
    assert batch.height > 10
    assert _same(_online(site, cfg, inputs, [1.0, 3.0, 9.99, 10.0, 12.5, 13.0]), batch)


def test_the_configs_that_need_the_whole_log_stay_batch():
    assert "latency_auto" in online.supported(IStateConfig())
    assert "reliable_negatives" in online.supported(IStateConfig(latency_auto=False, reliable_negatives=True))
    assert online.supported(IStateConfig(latency_auto=False)) is None
    with pytest.raises(ConfigError, match="latency_auto"):
        online.start(None, IStateConfig())
