"""``ignore = true`` in site.toml: the readers read the sensor, no tracker sees it."""

from __future__ import annotations

import shutil

import polars as pl
import pytest

from onebit.datasets.hallway_sim import write_hallway_dataset
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline
from onebit.pipeline.stages import without_ignored

FLICKER = "92"  # the printer room: made to flicker 200 times, then ignored


@pytest.fixture(scope="module")
def hallway(tmp_path_factory):
    data = write_hallway_dataset(tmp_path_factory.mktemp("hw") / "data", seed=1, duration=40.0, users=2)
    motion = pl.read_csv(data / "motion.csv", schema_overrides={"sensor": pl.String})
    flicker = pl.DataFrame(
        {
            "t": [0.5 + 0.25 * k for k in range(200)],
            "sensor": [FLICKER] * 200,
            "value": [(k + 1) % 2 for k in range(200)],
        }
    )
    pl.concat([motion, flicker.cast(motion.schema)]).sort("t").write_csv(data / "motion.csv")
    return data


@pytest.fixture(scope="module")
def plain_run(hallway, tmp_path_factory):
    return run_pipeline(hallway, tmp_path_factory.mktemp("plain") / "run", trackers=["hmm1"], rrd=False)


def test_without_the_flag_the_flicker_reaches_the_trackers(plain_run):
    assert plain_run.status["ignore"].startswith("skipped")
    hmm = pl.read_parquet(plain_run.out / "tables" / "hmm1_tracks.parquet")
    assert FLICKER in set(hmm["node"].drop_nulls())


def test_an_ignored_sensor_is_read_but_no_tracker_sees_it(hallway, plain_run, tmp_path):
    data = shutil.copytree(hallway, tmp_path / "data")
    site = (data / "site.toml").read_text()
    (data / "site.toml").write_text(site.replace(f'id = "{FLICKER}"\n', f'id = "{FLICKER}"\nignore = true\n', 1))
    res = run_pipeline(data, tmp_path / "run", trackers=["hmm1"], rrd=False)
    assert res.status["ignore"].startswith("ok"), res.status
    assert res.status["hmm1"].startswith("ok"), res.status["hmm1"]
    motion = pl.read_parquet(res.out / "tables" / "motion.parquet")
    read = motion.filter(pl.col("sensor") == FLICKER).height
    assert read >= 100  # read as any other sensor, as without the flag
    assert motion.equals(pl.read_parquet(plain_run.out / "tables" / "motion.parquet"))
    assert metric(res.report, "motion/rejected") == metric(plain_run.report, "motion/rejected")
    assert metric(res.report, "ignore/ignored_rows") == float(read)
    ignored = pl.read_parquet(res.out / "tables" / "ignored.parquet")
    assert ignored.rows() == [("motion", FLICKER, read)]
    hmm = pl.read_parquet(res.out / "tables" / "hmm1_tracks.parquet")
    assert FLICKER not in set(hmm["node"].drop_nulls())


def test_without_ignored_leaves_other_tables_alone():
    df = pl.DataFrame({"t": [0.0, 1.0], "sensor": ["a", "b"], "on": [True, False]})
    assert without_ignored("motion", df, frozenset({"a"}))["sensor"].to_list() == ["b"]
    assert without_ignored("truth_events", df, frozenset({"a"})).equals(df)
    assert without_ignored("motion", df, frozenset()) is df
    crossings = pl.DataFrame({"t": [0.0], "beam": ["a"], "direction": [1]})
    assert without_ignored("crossings", crossings, frozenset({"a"})).height == 0
