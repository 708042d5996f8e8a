"""The ``home`` scenario: 50 PIRs on a connected graph, residents sensed as PIRs sense them."""

from __future__ import annotations

import polars as pl

from onebit.core.site import load_site
from onebit.datasets.catalogue import get_scenario
from onebit.datasets.home_sim import HomeSimConfig, layout, simulate_home, write_home_dataset


def test_layout_is_fifty_sensors_on_one_connected_graph_with_rooms_joined_by_their_doors(tmp_path):
    pos, edges, rooms = layout()
    assert len(pos) == 50 and sum(len(v) for v in rooms.values()) == 50
    data = write_home_dataset(tmp_path / "home", seed=0, duration=600.0)
    site = load_site(data / "site.toml")
    g = site.sensor_graph.to_networkx(site)
    import networkx as nx

    assert nx.is_connected(g) and g.number_of_nodes() == 50 and site.targets == 2
    hall = set(rooms["hallway"])
    for room, nodes in rooms.items():  # a room reaches the rest only through one hallway node
        if room == "hallway":
            continue
        out = {b for a in nodes for b in g.neighbors(a) if b not in nodes}
        assert len(out) == 1 and out <= hall, room


def test_the_log_toggles_each_sensor_on_then_off_where_residents_are_and_is_deterministic(tmp_path):
    site = load_site(write_home_dataset(tmp_path / "h", seed=3, duration=1800.0) / "site.toml")
    cfg = HomeSimConfig(duration=1800.0, residents=2)
    a, b = simulate_home(site, cfg, seed=3), simulate_home(site, cfg, seed=3)
    assert a.toggles.equals(b.toggles) and a.samples.equals(b.samples)
    assert a.toggles.height > 0 and set(a.samples["target"].unique()) == {"resident1", "resident2"}
    per = a.toggles.sort(["sensor", "t"]).group_by("sensor", maintain_order=True).agg("value")
    for values in per["value"]:  # on, off, on, off, ...: starts on, alternates
        assert values[0] == 1 and all(x != y for x, y in zip(values, values[1:]))
    # a sensor turns on only where a resident is within its range at that time
    on = (
        a.toggles.filter(pl.col("value") == 1)
        .join(a.samples, on="t")
        .join(
            pl.DataFrame(
                {
                    "sensor": [m.id for m in site.motion_sensors],
                    "sx": [m.position[0] for m in site.motion_sensors],
                    "sy": [m.position[1] for m in site.motion_sensors],
                }
            ),
            on="sensor",
        )
    )
    near = on.with_columns(d=((pl.col("x") - pl.col("sx")) ** 2 + (pl.col("y") - pl.col("sy")) ** 2).sqrt())
    assert near.group_by(["t", "sensor"]).agg(pl.col("d").min())["d"].max() <= 1.6 + 1e-9


def test_scenario_is_listed(tmp_path):
    assert get_scenario("home").name == "home"
