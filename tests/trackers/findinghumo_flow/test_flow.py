"""findinghumo-flow: the minimum-cost flow against brute force, fragments and meetings, a
crossing put right, the stage contract."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.core.errors import ConfigError
from onebit.core.tables import TRACKS
from onebit.datasets.builtin import builtin_site
from onebit.datasets.hallway_sim import write_hallway_dataset
from onebit.models.graph_hmm.eatg import hop_matrix, layout_eatg
from onebit.readers.motion import read_motion_csv
from onebit.trackers.findinghumo_flow.association import chains, fragments, meetings, min_cost_cover
from onebit.trackers.findinghumo_flow.stage import FlowConfig, associate_paths, run_flow


def brute_force_cover(n, birth, death, joins):
    """Minimum cost over every set of chains covering ``0..n-1``: every successor function
    (each fragment: one allowed successor or none, no fragment with two predecessors)."""
    options = [[-1] + [g for (f, g) in joins if f == i] for i in range(n)]
    best = np.inf
    for succ in itertools.product(*options):
        used = [g for g in succ if g >= 0]
        if len(used) != len(set(used)):
            continue
        has_pred = set(used)
        cost = sum(birth[f] for f in range(n) if f not in has_pred)
        cost += sum(death[f] if succ[f] < 0 else joins[(f, succ[f])] for f in range(n))
        best = min(best, cost)
    return best


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 100_000), n=st.integers(1, 7), density=st.floats(0.1, 0.9))
def test_min_cost_cover_equals_brute_force(seed, n, density):
    """On small random DAGs of fragments (joins only forward in index = time) the flow's
    chains cost exactly the brute-force minimum, and they cover every fragment once."""
    rng = np.random.default_rng(seed)
    birth = rng.integers(0, 20, n).astype(float)
    death = rng.integers(0, 20, n).astype(float)
    joins = {(f, g): float(rng.integers(-5, 15)) for f in range(n) for g in range(f + 1, n) if rng.random() < density}
    succ, total = min_cost_cover(n, birth, death, joins)
    assert total == pytest.approx(brute_force_cover(n, birth, death, joins), abs=1e-6)
    covered = sorted(f for ch in chains(succ) for f in ch)
    assert covered == list(range(n))
    assert all((f, int(g)) in joins for f, g in enumerate(succ) if g >= 0)


@pytest.fixture(scope="module")
def hallway():
    site = builtin_site("hallway")
    g = site.sensor_graph
    return site, layout_eatg(g.nodes, hop_matrix(g.nodes, g.edges))


def _paths(eatg, seqs):
    idx = eatg.index
    return np.array([[idx[str(n)] if n is not None else -1 for n in s] for s in seqs], dtype=np.int64)


def _flags(site, eatg):
    g = site.sensor_graph
    arr = np.asarray(eatg.nodes)
    return np.isin(arr, list(g.entries) + list(g.exits)), np.isin(arr, list(g.entries)), np.isin(arr, list(g.exits))


def test_meetings_and_fragments(hallway):
    site, eatg = hallway
    decoded = _paths(
        eatg,
        [
            [97, 96, 95, 99, 99, 95, 96, 97],
            [110, 111, 111, 99, 99, 111, 110, 117],
        ],
    )
    feature, _, _ = _flags(site, eatg)
    meets = meetings(decoded, eatg.hops, feature)
    assert len(meets) == 1
    m = meets[0]
    assert m.tracks == (0, 1) and (m.s0, m.s1) == (3, 4) and 4 <= m.cut <= 5  # 95 and 111 are two hops apart
    frags = fragments(decoded, meets)
    assert [(f.track, f.start, f.end) for f in frags] == [(0, 0, m.cut), (0, m.cut, 8), (1, 0, m.cut), (1, m.cut, 8)]


def test_crossing_is_put_right(hallway):
    """Two users cross in the kitchen; the decoder bounced them back. The flow joins each
    incoming fragment to the outgoing one that goes on in its direction (a'')."""
    site, eatg = hallway
    decoded = _paths(
        eatg,
        [
            [97, 97, 96, 96, 95, 95, 99, 99, 95, 95, 96, 96, 97, 97],
            [117, 117, 110, 110, 111, 111, 99, 99, 111, 111, 110, 110, 117, 117],
        ],
    )
    feature, entries, exits = _flags(site, eatg)
    out, frags, ident, joins = associate_paths(
        decoded, eatg.hops, eatg.a1, eatg.a2, feature, entries, exits, run_start=0
    )
    names = [[eatg.nodes[j] for j in row] for row in out]
    assert sorted(names) == sorted(
        [
            ["97", "97", "96", "96", "95", "95", "99", "99", "111", "111", "110", "110", "117", "117"],
            ["117", "117", "110", "110", "111", "111", "99", "99", "95", "95", "96", "96", "97", "97"],
        ]
    )
    assert any(ch for *_, ch in joins)
    # continuity holds on every identity
    assert np.all(eatg.hops[out[:, :-1], out[:, 1:]] <= 1)


def test_users_walking_apart_are_kept(hallway):
    """No meeting, nothing to join: the decoded paths come back unchanged."""
    site, eatg = hallway
    decoded = _paths(eatg, [[97, 96, 95, 95, 96, 97], [117, 110, 111, 111, 110, 117]])
    feature, entries, exits = _flags(site, eatg)
    out, frags, ident, joins = associate_paths(decoded, eatg.hops, eatg.a1, eatg.a2, feature, entries, exits)
    assert joins == [] and np.array_equal(out, decoded)


def test_a_vanished_track_goes_on_as_the_next_one(hallway):
    """A track lost for two slots mid-corridor continues on the track that starts near it
    (the gap join, EATG A' over the gap), instead of a birth and a death away from the doors."""
    site, eatg = hallway
    decoded = _paths(
        eatg,
        [
            [97, 96, 95, None, None, None, None, None],
            [None, None, None, None, None, 111, 110, 117],
        ],
    )
    feature, entries, exits = _flags(site, eatg)
    out, frags, ident, joins = associate_paths(
        decoded, eatg.hops, eatg.a1, eatg.a2, feature, entries, exits, run_start=0
    )
    assert out.shape[0] == 1 and len(set(ident.tolist())) == 1
    assert [eatg.nodes[j] if j >= 0 else None for j in out[0]] == ["97", "96", "95", None, None, "111", "110", "117"]


def test_config_errors_name_the_field():
    with pytest.raises(ConfigError, match="decoder"):
        FlowConfig(decoder="nope")
    with pytest.raises(ConfigError, match="max_gap"):
        FlowConfig(max_gap=-1)


def test_stage_contract(tmp_path, hallway):
    site, _ = hallway
    ds = write_hallway_dataset(tmp_path / "d", seed=4, duration=40.0, users=2)
    mo = read_motion_csv(ds / "motion.csv", [m.id for m in site.motion_sensors]).motion
    out1 = run_flow({"motion": mo}, site, FlowConfig())
    out2 = run_flow({"motion": mo}, site, FlowConfig())
    assert out1["tracks"].schema == TRACKS
    assert out1["tracks"].equals(out2["tracks"]) and out1["joins"].equals(out2["joins"])  # deterministic
    # every fragment belongs to exactly one identity
    assert out1["fragments"]["identity"].min() >= 0
    empty = run_flow({"motion": mo.clear()}, site, FlowConfig())
    assert empty["tracks"].height == 0 and empty["tracks"].schema == TRACKS
