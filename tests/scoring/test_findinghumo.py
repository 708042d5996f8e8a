"""HMM scoring: tracks matched to users by minimum summed hop error; a missed slot = diameter."""

from __future__ import annotations

import polars as pl
import pytest

from onebit.core.tables import SCORES
from onebit.models.graph_hmm.eatg import hop_matrix
from onebit.scoring.findinghumo import _truth_nodes, score, truth_nodes


def test_users_take_the_track_of_least_summed_hops_and_missed_slots_cost_the_diameter(hallway_site):
    site = hallway_site
    g = site.sensor_graph
    hops = hop_matrix(g.nodes, g.edges)
    diameter = int(hops[hops <= len(g.nodes)].max())
    a, b = g.edges[0]
    far = g.nodes[int(hops[g.nodes.index(a)].argmax())]
    xy = {m.id: m.position for m in site.motion_sensors}
    truth = pl.DataFrame(
        {
            "t": [0.5, 1.5, 2.5] * 2,
            "target": ["u1"] * 3 + ["u2"] * 3,
            "x": [xy[a][0]] * 3 + [xy[far][0]] * 3,
            "y": [xy[a][1]] * 3 + [xy[far][1]] * 3,
        }
    )
    # k1 sits on u2's node; k2 on u1's node but misses the last slot
    tracks = pl.DataFrame(
        {
            "tracker": "hmm1",
            "track": ["k1"] * 3 + ["k2"] * 2,
            "t": [0.5, 1.5, 2.5, 0.5, 1.5],
            "node": [far] * 3 + [a, b],
        }
    )
    rows, made = score("hmm1", {"hmm1_tracks": tracks, "truth": truth}, site)
    m = {r[1]: r[2] for r in rows}
    assert m["users_true"] == 2 and m["users_decoded"] == 2
    assert m["hop_error/u2"] == 0.0
    assert m["hop_error/u1"] == pytest.approx((0 + 1 + diameter) / 3)
    assert m["hop_error"] == pytest.approx((0 + 1 + diameter) / 6)
    assert m["slots_exact"] == pytest.approx(4 / 6)
    sc = made["hmm1_scores"]
    assert sc.schema == SCORES and dict(sc.select("track", "target").unique().iter_rows()) == {"k1": "u2", "k2": "u1"}


def test_truth_nodes_answers_the_same_truth_once_and_a_new_truth_anew(hallway_site):
    xy = [m.position for m in hallway_site.motion_sensors]
    one = pl.DataFrame({"t": [0.0, 1.0], "target": ["u", "u"], "x": [xy[0][0], xy[1][0]], "y": [xy[0][1], xy[1][1]]})
    other = one.with_columns(x=pl.Series([xy[2][0], xy[3][0]]), y=pl.Series([xy[2][1], xy[3][1]]))
    first = truth_nodes(one, hallway_site)
    assert truth_nodes(one, hallway_site) is first  # the same objects: the remembered answer
    again = truth_nodes(other, hallway_site)
    assert again["node"].to_list() == _truth_nodes(other, hallway_site)["node"].to_list()
    assert again["node"].to_list() != first["node"].to_list()
    assert truth_nodes(one, hallway_site)["node"].to_list() == first["node"].to_list()
