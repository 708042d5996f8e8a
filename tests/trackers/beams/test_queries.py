"""Queries of section IV-F-1 on hand-made assignments, and the beams stage end to end."""

from __future__ import annotations

import polars as pl
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.core.region_graph import build_region_graph
from onebit.datasets.beams_sim import write_beams_dataset
from onebit.datasets.builtin import builtin_site
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline
from onebit.trackers.beams import queries
from onebit.viz.beams import beam_midpoints
from onebit.viz.inspect import entity_paths


def _assignment() -> pl.DataFrame:
    """Hand-made: agent A r1 -> r2 at 1 s, agent B r1 -> r2 at 2 s, A r2 -> r3 at 65 s,
    B r2 -> r1 at 70 s, and an unexplained crossing (track null) r3 -> r2 at 71 s."""
    return pl.DataFrame(
        {
            "t": [1.0, 2.0, 65.0, 70.0, 71.0],
            "track": ["A", "B", "A", "B", None],
            "source": ["r1", "r1", "r2", "r2", "r3"],
            "region": ["r2", "r2", "r3", "r1", "r2"],
        }
    )


STARTS = pl.DataFrame({"track": ["A", "B", "C"], "t": [0.0] * 3, "region": ["r1", "r1", "r3"]})
REGIONS = ("r1", "r2", "r3", "r4")


def test_visits_most_visited_first():
    v = queries.visits_per_region(_assignment(), REGIONS)
    assert v.rows() == [("r2", 2), ("r1", 1), ("r3", 1), ("r4", 0)]


def test_traffic_per_bucket():
    tr = queries.traffic_per_region(_assignment(), 60.0)
    rows = {(r["bucket"], r["region"]): (r["entries"], r["exits"], r["traffic"]) for r in tr.iter_rows(named=True)}
    assert rows == {
        (0, "r1"): (0, 2, 2),
        (0, "r2"): (2, 0, 2),
        (1, "r2"): (0, 2, 2),
        (1, "r3"): (1, 0, 1),
        (1, "r1"): (1, 0, 1),
    }
    assert tr["t_start"].unique().sort().to_list() == [0.0, 60.0]
    with pytest.raises(ValueError, match="bucket_s"):
        queries.traffic_per_region(_assignment(), 0.0)


def test_occupancy_counts_bodies():
    occ = queries.occupancy(_assignment(), STARTS, REGIONS)
    last = occ.group_by("region").agg(pl.col("count").last()).sort("region")
    assert last.rows() == [("r1", 1), ("r2", 0), ("r3", 2), ("r4", 0)]
    r2 = occ.filter(pl.col("region") == "r2")
    assert r2["t"].to_list() == [0.0, 1.0, 2.0, 65.0, 70.0] and r2["count"].to_list() == [0, 1, 2, 1, 0]
    # the count of bodies is conserved after every crossing
    total = (
        occ.sort("t", maintain_order=True).group_by("region", maintain_order=True).agg(pl.all().last())["count"].sum()
    )
    assert total == STARTS.height


def test_intervals_over_threshold():
    occ = queries.occupancy(_assignment(), STARTS, REGIONS)
    over = queries.intervals_over_threshold(occ, 1, t_end=80.0)
    assert over.rows() == [("r1", 0.0, 1.0, 1.0, 2), ("r2", 2.0, 65.0, 63.0, 2), ("r3", 65.0, 80.0, 15.0, 2)]
    assert queries.intervals_over_threshold(occ, 2).height == 0
    assert queries.intervals_over_threshold(occ.clear(), 0).height == 0


@settings(max_examples=50, deadline=None)
@given(
    st.lists(
        st.sampled_from(["a", "a^-1", "b", "b^-1", "c", "c^-1", "d", "d^-1", "e", "e^-1", "f", "f^-1", "g", "g^-1"]),
        max_size=30,
    )
)
def test_visits_of_r4_count_d_f_g_inverse(word):
    """Section IV-F-1: the visitors of r4 are the occurrences of d, f and g^-1."""
    rg = build_region_graph(builtin_site("building"))
    beams = [w[0] for w in word]
    dirs = [-1 if w.endswith("^-1") else 1 for w in word]
    src, tgt = rg.endpoint_arrays(pl.Series(beams, dtype=pl.String), dirs)
    names = list(rg.names)
    a = pl.DataFrame(
        {
            "t": [float(i) for i in range(len(word))],
            "source": [names[i] for i in src],
            "region": [names[i] for i in tgt],
        },
        schema={"t": pl.Float64, "source": pl.String, "region": pl.String},
    )
    v = dict(queries.visits_per_region(a, rg.names).rows())
    assert v["r4"] == sum(w in ("d", "f", "g^-1") for w in word)
    assert sum(v.values()) == len(word)


# ----------------------------------------------------------------- end to end


@pytest.fixture(scope="module")
def building_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("bq")
    data = write_beams_dataset(root / "data", "beams-building", seed=2, duration=90.0, drop=0.0, camera=False)
    cfg = {"beams": {"traffic_bucket_s": 30.0, "occupancy_threshold": 1, "capacity": {"r2": 1}}}
    res = run_pipeline(data, root / "run", trackers=("beams",), config=cfg)
    return res


def test_pipeline_writes_query_tables_and_report_rows(building_run):
    res = building_run
    assert res.ok, res.status
    tables = res.out / "tables"
    for name in ("beams_visits", "beams_traffic", "beams_occupancy", "beams_over_threshold", "beams_unexplained"):
        assert (tables / f"{name}.parquet").exists(), name
    visits = pl.read_parquet(tables / "beams_visits.parquet")
    assert visits["visits"].is_sorted(descending=True)
    assert metric(res.report, "beams/most_visited_visits") == visits["visits"][0]
    over = pl.read_parquet(tables / "beams_over_threshold.parquet")
    assert metric(res.report, "beams/over_threshold_intervals") == over.height
    a = pl.read_parquet(tables / "beams_assignment.parquet")
    assert metric(res.report, "beams/ambiguous_crossings") == a["ambiguous"].sum()
    un = pl.read_parquet(tables / "beams_unexplained.parquet")
    assert metric(res.report, "beams/unexplained_crossings") == un.height == a["track"].null_count()
    occ = pl.read_parquet(tables / "beams_occupancy.parquet")
    assert occ.filter(pl.col("region") == "r2")["count"].max() <= 1
    assert un.height > 0 and un["reason"].str.contains("r2").all()  # the bound binds on this run
    traffic = pl.read_parquet(tables / "beams_traffic.parquet")
    assert traffic["traffic"].sum() == 2 * (a.height - un.height)
    assert "traffic_bucket_s = 30.0" in (res.out / "run.toml").read_text()


def test_rrd_holds_occupancy_region_paths_and_marks(building_run):
    res = building_run
    ents = set(entity_paths(res.out / "rrd" / "beams.rrd"))
    assert {f"beams/occupancy/r{k}" for k in range(1, 7)} <= ents
    agents = pl.read_parquet(res.out / "tables" / "beams_agents.parquet")
    for track in agents["track"]:
        assert f"beams/tracks/{track}/regions" in ents and f"beams/tracks/{track}" in ents
    a = pl.read_parquet(res.out / "tables" / "beams_assignment.parquet")
    # this run has both kinds of marked crossings, so the marks must be in the recording
    assert a["ambiguous"].any() and a["track"].null_count() > 0
    assert {"beams/ambiguous", "beams/ambiguous/log", "beams/unexplained", "beams/unexplained/log"} <= ents


def test_beam_midpoints_are_gathered_per_crossing_and_unknown_beams_named():
    import numpy as np

    site = builtin_site("building")
    ids = [b.id for b in site.beams]
    want = {b.id: np.asarray(b.line.interpolate(0.5, normalized=True).coords[0]) for b in site.beams}
    order = [ids[k] for k in np.random.default_rng(0).integers(0, len(ids), 50)]
    got = beam_midpoints(site, pl.Series(order))
    assert got.shape == (50, 2)
    np.testing.assert_allclose(got, np.array([want[b] for b in order]))
    assert beam_midpoints(site, []).shape == (0, 2)
    with pytest.raises(ValueError, match="'zz'"):
        beam_midpoints(site, ["a", "zz"])
