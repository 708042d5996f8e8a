"""The hallway site and simulator: paper node ids and adjacency, determinism, raw log sanity."""

from __future__ import annotations

import networkx as nx
import numpy as np
import polars as pl
import pytest

from onebit.core.errors import ConfigError
from onebit.datasets.builtin import builtin_site
from onebit.datasets.catalogue import get_scenario
from onebit.datasets.hallway_sim import (
    ROUTE_EAST,
    ROUTE_WEST,
    HallwaySimConfig,
    simulate_hallway,
    write_hallway_dataset,
)
from onebit.readers.motion import read_motion_csv
from onebit.readers.tables_csv import read_truth_csv


def test_site_is_the_papers_floor():
    site = builtin_site("hallway")
    g = site.sensor_graph.to_networkx(site)
    assert len(site.motion_sensors) == 20 and nx.is_connected(g)
    ids = {m.id for m in site.motion_sensors}
    assert {
        "92",
        "93",
        "94",
        "95",
        "96",
        "97",
        "99",
        "100",
        "101",
        "102",
        "103",
        "104",
        "110",
        "111",
        "114",
        "117",
        "118",
    } <= ids
    assert all(92 <= int(i) <= 118 for i in ids)
    minx, miny, maxx, maxy = site.boundary.bounds
    assert (maxx - minx, maxy - miny) == (30.0, 30.0)
    assert g.has_edge("96", "94") and not g.has_edge("96", "93")  # "...96 -> 94 instead of 96 -> 93"
    assert ("104", "103") in site.sensor_graph.signatures and g.has_edge("97", "104")  # entry 104->103, exit 97->104
    # Fig. 5(b): the 1-hop neighbours of the path's nodes are 117, 96, 101
    path = {"110", "111", "114", "99", "95"}
    assert set().union(*(set(g[n]) for n in path)) - path == {"117", "96", "101"}


def test_simulation_is_deterministic_and_truthful(tmp_path):
    a = write_hallway_dataset(tmp_path / "a", seed=5, duration=60.0, users=3)
    b = write_hallway_dataset(tmp_path / "b", seed=5, duration=60.0, users=3)
    assert (a / "motion.csv").read_bytes() == (b / "motion.csv").read_bytes()
    assert (a / "truth.csv").read_bytes() == (b / "truth.csv").read_bytes()
    site = builtin_site("hallway")
    read = read_motion_csv(a / "motion.csv", [m.id for m in site.motion_sensors])
    assert read.rejects.height == 0  # alternating, sorted, known sensors
    truth, rej = read_truth_csv(a / "truth.csv")
    assert rej.height == 0 and truth["target"].n_unique() == 3
    raw = pl.read_csv(a / "truth.csv", schema_overrides={"node": pl.String})
    # scripted routes (default): every user is at an end of its west-east route when the
    # experiment starts, pairwise >= 2 hops apart (countable by K_now), and they set off at staggered times
    first = raw.sort("t").group_by("target", maintain_order=True).first()
    assert set(first["node"]) <= set(ROUTE_WEST + ROUTE_EAST) and set(first["t"]) == {1.0}
    g = site.sensor_graph.to_networkx(site)
    starts = first["node"].to_list()
    assert all(nx.shortest_path_length(g, a, b) >= 2 for i, a in enumerate(starts) for b in starts[i + 1 :])
    moved = (
        raw.sort("t")
        .filter(pl.col("node") != pl.col("node").first().over("target"))
        .group_by("target")
        .agg(pl.col("t").min())
    )
    assert moved["t"].n_unique() == 3
    # random destinations: users enter through the door
    c = write_hallway_dataset(tmp_path / "c", seed=5, duration=60.0, users=3, walk="random")
    rnd = pl.read_csv(c / "truth.csv", schema_overrides={"node": pl.String})
    first = rnd.sort("t").group_by("target", maintain_order=True).first()
    assert set(first["node"]) == {"104"} and first["t"].n_unique() == 3
    # truth moves at walking speed and every node is a graph node
    for _, g in raw.group_by("target"):
        g = g.sort("t")
        v = np.hypot(np.diff(g["x"].to_numpy()), np.diff(g["y"].to_numpy())) / np.diff(g["t"].to_numpy())
        assert v.max() < 2.5
    assert set(raw["node"].drop_nulls()) <= {m.id for m in site.motion_sensors}


def test_users_cross_and_leave():
    site = builtin_site("hallway")
    sim = simulate_hallway(site, HallwaySimConfig(duration=120.0, users=3, exits=1), seed=2)
    s = sim.samples
    ends = s.group_by("target").agg(pl.col("t").max())
    assert (ends["t"] < 110.0).sum() == 1  # one user left before the end
    both = s.with_columns(slot=pl.col("t").floor()).group_by("slot", "node").agg(pl.col("target").n_unique().alias("n"))
    assert (both["n"] >= 2).any()  # paths overlap: two users at one node at once


def test_scenario_registry_and_params(tmp_path):
    sc = get_scenario("hallway")
    out = sc.write(tmp_path / "x", seed=1, duration=20.0, agents=2, drop=0.0, camera=False, params={"exits": "0"})
    assert (out / "site.toml").exists() and (out / "motion.csv").exists()
    with pytest.raises(ConfigError, match="unknown --param"):
        sc.write(tmp_path / "y", seed=1, duration=20.0, agents=2, drop=0.0, camera=False, params={"bogus": "1"})
    with pytest.raises(ConfigError, match="exits"):
        HallwaySimConfig(users=2, exits=3)
