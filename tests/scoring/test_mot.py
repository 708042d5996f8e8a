"""MOT metrics: known answers on small scenes, cross-checked against motmetrics and trackeval
called directly, and the tracker adapters (points, sensor-graph nodes, held regions)."""

from __future__ import annotations

import motmetrics as mm
import numpy as np
import polars as pl
import pytest
from trackeval.metrics import CLEAR, HOTA, Identity

from onebit.core.errors import ConfigError, OnebitError
from onebit.core.site import site_from_dict
from onebit.core.tables import TRUTH
from onebit.pipeline.stages import TRACKERS
from onebit.scoring.crossings import ScoresConfig
from onebit.scoring.mot import mot_metrics, mot_rows, node_frames, point_frames, region_frames, similarity

ALPHAS = np.arange(0.05, 0.99, 0.05)

#: each tracker's gate, as its TrackerEntry declares it
GATE = {e.name: e.gate for e in TRACKERS}


def scene():
    """10 frames. Target a: track x throughout (d = 0.15). Target b: track y on frames 0-4
    (d = 0.25), then track z on 5-9 (d = 0.35): one ID switch. Target c on frames 0-1: never
    tracked (2 misses). Track f on frame 3 far from everyone (1 false positive)."""
    obj = [(float(f), g) for f in range(10) for g in ("a", "b")] + [(0.0, "c"), (1.0, "c")]
    hyp = [(float(f), "x") for f in range(10)] + [(float(f), "y" if f < 5 else "z") for f in range(10)] + [(3.0, "f")]
    near = {("a", "x"): 0.15, ("b", "y"): 0.25, ("b", "z"): 0.35}
    objects = pl.DataFrame(obj, schema={"t": pl.Float64, "target": pl.String}, orient="row")
    hypotheses = pl.DataFrame(hyp, schema={"t": pl.Float64, "track": pl.String}, orient="row")
    distances = objects.join(hypotheses, on="t").with_columns(
        distance=pl.struct("target", "track").map_elements(
            lambda r: near.get((r["target"], r["track"]), 5.0), return_dtype=pl.Float64
        )
    )
    return objects, hypotheses, distances


def direct_motmetrics(objects, hypotheses, distances, gate):
    """motmetrics driven by hand, frame by frame, with the test's own bookkeeping."""
    acc = mm.MOTAccumulator(auto_id=True)
    d = {(t, g, k): v for t, g, k, v in distances.select("t", "target", "track", "distance").iter_rows()}
    gi = {g: i for i, g in enumerate(sorted(set(objects["target"])))}  # integer ids: motmetrics 1.4
    ki = {k: i for i, k in enumerate(sorted(set(hypotheses["track"])))}  # fails on strings with pandas 3
    for t in sorted(set(objects["t"]) | set(hypotheses["t"])):
        o = sorted(objects.filter(pl.col("t") == t)["target"])
        h = sorted(hypotheses.filter(pl.col("t") == t)["track"])
        D = np.array([[d.get((t, g, k), np.nan) for k in h] for g in o]).reshape(len(o), len(h))
        acc.update([gi[g] for g in o], [ki[k] for k in h], np.where(D <= gate, D, np.nan))
    return mm.metrics.create().compute(acc, metrics=["mota", "motp", "idf1", "num_switches"], return_dataframe=False)


def direct_trackeval(objects, hypotheses, distances, gate):
    """trackeval HOTA, CLEAR (threshold 0.5) and Identity on the test's own data dict."""
    gi = {g: i for i, g in enumerate(sorted(set(objects["target"])))}
    ki = {k: i for i, k in enumerate(sorted(set(hypotheses["track"])))}
    d = {(t, g, k): v for t, g, k, v in distances.select("t", "target", "track", "distance").iter_rows()}
    data = {"gt_ids": [], "tracker_ids": [], "similarity_scores": []}
    times = sorted(set(objects["t"]) | set(hypotheses["t"]))
    for t in times:
        o = sorted(objects.filter(pl.col("t") == t)["target"])
        h = sorted(hypotheses.filter(pl.col("t") == t)["track"])
        s = np.array([[max(0.0, 1 - d.get((t, g, k), np.inf) / (2 * gate)) for k in h] for g in o]).reshape(
            len(o), len(h)
        )
        data["gt_ids"].append(np.array([gi[g] for g in o], dtype=int))
        data["tracker_ids"].append(np.array([ki[k] for k in h], dtype=int))
        data["similarity_scores"].append(s)
    data.update(
        num_timesteps=len(times),
        num_gt_ids=len(gi),
        num_tracker_ids=len(ki),
        num_gt_dets=objects.height,
        num_tracker_dets=hypotheses.height,
    )
    quiet = {"PRINT_CONFIG": False}
    return HOTA().eval_sequence(data), CLEAR(quiet).eval_sequence(data), Identity(quiet).eval_sequence(data)


def test_known_scene_has_the_known_answers():
    m = mot_metrics(*scene(), gate=1.0)
    assert m["objects"] == 22 and m["frames"] == 10
    assert m["misses"] == 2 and m["false_positives"] == 1 and m["id_switches"] == 1
    assert m["mota"] == pytest.approx(1 - (2 + 1 + 1) / 22)
    assert m["motp"] == pytest.approx((10 * 0.15 + 5 * 0.25 + 5 * 0.35) / 20)
    # IDF1: a<->x (10 IDTP) and b<->y or z (5): IDTP 15 of 22 truth and 21 track samples
    assert m["idf1"] == pytest.approx(2 * 15 / (22 + 21))
    # HOTA: similarities 0.925 (a-x), 0.875 (b-y), 0.825 (b-z); alpha <= 0.80 matches all
    # 20, 0.85 matches a-x and b-y, 0.90 only a-x, 0.95 none
    det = np.r_[[20 / 23] * 16, 15 / (15 + 7 + 6), 10 / (10 + 12 + 11), 0.0]
    ass = np.r_[[(10 + 5 * 0.5 + 5 * 0.5) / 20] * 16, (10 + 5 * 0.5) / 15, 1.0, 0.0]
    assert m["deta"] == pytest.approx(det.mean())
    assert m["assa"] == pytest.approx(ass.mean())
    assert m["hota"] == pytest.approx(np.sqrt(det * ass).mean())


def _random_scene(seed: int):
    rng = np.random.default_rng(seed)
    T, G, K = 12, 3, 4
    truth = rng.uniform(0, 10, (T, G, 2))
    obj = [(float(t), f"g{g}") for t in range(T) for g in range(G) if rng.random() < 0.85]
    hyp, pos = [], {}
    for t in range(T):
        for k in range(K):
            if rng.random() < 0.8:
                g = (k + (t > 6)) % G  # tracks swap targets halfway
                pos[(t, f"k{k}")] = truth[t, g] + rng.normal(0, 0.6, 2)
                hyp.append((float(t), f"k{k}"))
    objects = pl.DataFrame(obj, schema={"t": pl.Float64, "target": pl.String}, orient="row")
    hypotheses = pl.DataFrame(hyp, schema={"t": pl.Float64, "track": pl.String}, orient="row")
    pairs = objects.join(hypotheses, on="t")
    d = [float(np.hypot(*(truth[int(t), int(g[1:])] - pos[(int(t), k)]))) for t, g, k in pairs.iter_rows()]
    return objects, hypotheses, pairs.with_columns(distance=pl.Series(d))


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("gate", [0.5, 1.0, 2.0])
def test_matches_motmetrics_and_trackeval_called_directly(seed, gate):
    objects, hypotheses, distances = _random_scene(seed)
    m = mot_metrics(objects, hypotheses, distances, gate=gate)
    ref = direct_motmetrics(objects, hypotheses, distances, gate)
    assert m["mota"] == pytest.approx(ref["mota"])
    assert m["motp"] == pytest.approx(ref["motp"], nan_ok=True)
    assert m["idf1"] == pytest.approx(ref["idf1"])
    assert m["id_switches"] == ref["num_switches"]
    hota, _, ident = direct_trackeval(objects, hypotheses, distances, gate)
    assert m["hota"] == pytest.approx(hota["HOTA"].mean())
    assert m["deta"] == pytest.approx(hota["DetA"].mean())
    assert m["assa"] == pytest.approx(hota["AssA"].mean())
    # the gate is trackeval's similarity 0.5: its global ID matching agrees with motmetrics'
    assert ident["IDF1"] == pytest.approx(m["idf1"])


def test_trackeval_clear_agrees_with_motmetrics_on_an_unambiguous_scene():
    """The two CLEAR implementations differ in how a frame's matching continues identities
    (motmetrics keeps last frame's pairs first, then minimum distance; trackeval maximises
    1000 x continuation + similarity jointly), so on crowded scenes their ID switches can
    differ by a few; where no frame is ambiguous they agree exactly."""
    m = mot_metrics(*scene(), gate=1.0)
    _, clear, ident = direct_trackeval(*scene(), 1.0)
    assert clear["MOTA"] == pytest.approx(m["mota"])
    assert (clear["IDSW"], clear["CLR_FN"], clear["CLR_FP"]) == (m["id_switches"], m["misses"], m["false_positives"])
    assert ident["IDF1"] == pytest.approx(m["idf1"])


def test_similarity_puts_the_gate_at_one_half():
    np.testing.assert_allclose(similarity(np.array([0.0, 1.0, 2.0, 3.0, np.nan]), 1.0), [1.0, 0.5, 0.0, 0.0, 0.0])


def test_empty_frames_give_nan_or_zero_never_an_error():
    objects, hypotheses, distances = scene()
    no_tracks = mot_metrics(objects, hypotheses.clear(), distances.clear(), gate=1.0)
    assert no_tracks["mota"] == 0.0 and no_tracks["misses"] == 22 and no_tracks["hota"] == 0.0
    assert np.isnan(no_tracks["motp"])
    no_truth = mot_metrics(objects.clear(), hypotheses, distances.clear(), gate=1.0)
    assert np.isnan(no_truth["mota"]) and no_truth["false_positives"] == hypotheses.height
    nothing = mot_metrics(objects.clear(), hypotheses.clear(), distances.clear(), gate=1.0)
    assert nothing["frames"] == 0 and np.isnan(nothing["mota"])
    with pytest.raises(OnebitError, match="gate=0"):
        mot_metrics(objects, hypotheses, distances, gate=0)


def test_every_tracker_has_a_gate_with_a_reason():
    for e in TRACKERS:
        g = e.gate
        assert g is not None and g.size > 0 and g.reason, e.name
        assert (g.unit == "hops") == (g.space in ("node", "region")), e.name


def _truth(rows):
    return (
        pl.DataFrame(
            rows, schema={"t": pl.Float64, "target": pl.String, "x": pl.Float64, "y": pl.Float64}, orient="row"
        )
        .with_columns(region=pl.lit(None, pl.String), node=pl.lit(None, pl.String))
        .select(list(TRUTH))
    )


def test_point_frames_score_every_truth_frame(hallway_site):
    """Every truth frame is a frame; a tracker sample holds for half its period around it; the
    truth frames it does not reach count their targets as misses."""
    truth = _truth([(t / 10, "a", t / 10, 0.0) for t in range(0, 101)])  # 10 Hz, x = t
    tracks = pl.DataFrame(
        {"track": ["k"] * 5, "t": [2.0, 4.0, 6.0, 8.0, 10.0], "x": [2.0, 4.5, 6.0, 8.0, None], "y": [0.0] * 5}
    )
    obj, hyp, dist = point_frames(tracks, truth)
    assert obj.height == 101  # every truth frame, the track's samples or not
    held = [t / 10 for t in range(10, 91)]  # within 1 s (half the track's 2 s period) of a sample with a position
    assert hyp["t"].to_list() == pytest.approx(held)
    d = dict(zip(dist["t"].to_list(), dist["distance"].to_list()))
    assert d[3.0] == pytest.approx(1.5) and d[4.0] == pytest.approx(0.5) and d[7.0] == pytest.approx(1.0)
    rows = dict(
        (r[1], r[2])
        for r in mot_rows("intruder", GATE["intruder"], {"intruder_tracks": tracks, "truth": truth}, hallway_site, None)
    )
    assert rows["mot_frames"] == 101 and rows["mot_misses"] == 101 - 81
    assert rows["mota"] == pytest.approx(1 - 20 / 101) and rows["mot_gate"] == 2.0
    # at 1 m the frames 1.5 m and 1.1-1.4 m off the 4.5 estimate are misses and false positives
    far = sum(1 for t in held if abs(t - 4.5) > 1.0 + 1e-9 and 3.0 <= t <= 5.0)
    assert rows["misses@1m"] == 20 + far and rows["false_positives@1m"] == far
    assert rows["count_error"] == pytest.approx(20 / 101) and rows["max_tracks"] == 1


def test_a_silent_tracker_scores_every_miss(hallway_site):
    """A tracker silent while truth is present: every present target at every truth frame is a
    miss, MOTA <= 0 (never NaN, never a score over the few frames it spoke)."""
    truth = _truth([(t / 2, g, 5.0 + t / 4, 5.0 + k) for t in range(40) for k, g in enumerate("ab")])
    silent = pl.DataFrame(schema={"track": pl.String, "t": pl.Float64, "x": pl.Float64, "y": pl.Float64})
    rows = dict(
        (r[1], r[2])
        for r in mot_rows("istate", GATE["istate"], {"istate_tracks": silent, "truth": truth}, hallway_site, None)
    )
    assert rows["mota@1m"] <= 0 and rows["misses@1m"] == truth.height == 80 and rows["false_positives@1m"] == 0
    assert rows["count_error"] == 2.0
    # a tracker that speaks at 4 of the 40 frames is scored on all 40
    few = pl.DataFrame({"track": ["k"] * 4, "t": [0.0, 5.0, 10.0, 15.0], "x": [5.0, 6.25, 7.5, 8.75], "y": [5.0] * 4})
    obj, hyp, dist = point_frames(few, truth)
    assert (
        obj["t"].n_unique() == 40 and hyp["t"].n_unique() == 36
    )  # each sample holds 2.5 s either side (its 5 s period): 0 .. 17.5 s
    m = mot_metrics(obj, hyp, dist, gate=1.0)
    assert m["objects"] == 80 and m["misses"] >= 80 - 36 and m["frames"] == 40


def test_tracks_where_nobody_is_present_are_false_positives(hallway_site):
    truth = _truth([(float(t), "a", 1.0, 1.0) for t in range(5)])
    tracks = pl.DataFrame({"track": ["k"] * 10, "t": [float(t) for t in range(10)], "x": [1.0] * 10, "y": [1.0] * 10})
    obj, hyp, dist = point_frames(tracks, truth)
    assert hyp.height == 10 and obj.height == 5  # the tracker's times 5..9 are frames with no object
    m = mot_metrics(obj, hyp, dist, gate=1.0)
    assert m["false_positives"] == 5 and m["misses"] == 0 and m["mota"] == pytest.approx(0.0)


def test_metric_gates_are_configurable_and_in_world_units(hallway_site):
    """The gates are metres, converted to the site's units; [scores] gates_m sets them."""
    feet = site_from_dict({"units": "ft", "boundary": {"polygon": [[0, 0], [30, 0], [30, 30], [0, 30]]}})
    truth = _truth([(float(t), "a", 10.0, 10.0) for t in range(10)])
    off = 1.2 / 0.3048  # 1.2 m in feet
    tracks = pl.DataFrame(
        {"track": ["k"] * 10, "t": [float(t) for t in range(10)], "x": [10.0 + off] * 10, "y": [10.0] * 10}
    )
    rows = dict(
        (r[1], r[2]) for r in mot_rows("x", None, {"x_tracks": tracks, "truth": truth}, feet, None, gates_m=(1.0, 1.5))
    )
    assert rows["mota@1m"] == -1.0 and rows["misses@1m"] == 10  # 1.2 m off: outside 1 m
    assert rows["mota@1.5m"] == 1.0 and rows["motp@1.5m"] == pytest.approx(off)
    assert ScoresConfig(gates_m=[1.5, 1.0]).gates_m == (1.5, 1.0) and ScoresConfig(gates_m=2).gates_m == (2.0,)
    for bad in ([], [0.0], ["1"], [float("nan")]):
        if bad == []:
            assert ScoresConfig(gates_m=bad).gates_m == ()
            continue
        with pytest.raises(ConfigError, match="gates_m"):
            ScoresConfig(gates_m=bad)


def test_paper_gate_rows_say_their_gate(hallway_site):
    truth = _truth([(float(t), "a", 1.0, 1.0) for t in range(3)])
    tracks = pl.DataFrame({"track": ["k"] * 3, "t": [0.0, 1.0, 2.0], "x": [1.0] * 3, "y": [1.0] * 3})
    units = {
        r[1]: r[3]
        for r in mot_rows("intruder", GATE["intruder"], {"intruder_tracks": tracks, "truth": truth}, hallway_site, None)
    }
    assert units["mota"] == "fraction @ 2 cells" and units["mota@1m"] == "fraction"


def test_node_frames_measure_hops_on_the_sensor_graph(hallway_site):
    site = hallway_site
    nodes, edges = site.sensor_graph.nodes, site.sensor_graph.edges
    a, b = edges[0]
    far = next(n for n in nodes if n not in (a, b) and (a, n) not in edges and (n, a) not in edges)
    xy = {m.id: m.position for m in site.motion_sensors}
    truth = _truth([(float(t), "u", *xy[a]) for t in range(4)])
    tracks = pl.DataFrame({"track": ["k"] * 4, "t": [0.0, 1.0, 2.0, 3.0], "node": [a, b, a, far]})
    obj, hyp, dist = node_frames(tracks, truth, site)
    assert dist.sort("t")["distance"].to_list()[:3] == [0.0, 1.0, 0.0]
    m = mot_metrics(obj, hyp, dist, gate=1.0)
    assert m["misses"] == 1 and m["false_positives"] == 1 and m["motp"] == pytest.approx(1 / 3)


def test_region_frames_hold_the_last_region_of_an_event_track(lab):
    site, rg = lab
    r0, r1 = next((s, t) for s, t, *_ in rg.graph.edges if s != t)
    p0, p1 = (rg.polygons[rg.index[r]].representative_point() for r in (r0, r1))
    truth = _truth([(float(t), "a", *((p0 if t < 5 else p1).coords[0])) for t in range(10)])
    tracks = pl.DataFrame({"track": ["k", "k"], "t": [1.0, 6.0], "region": [r0, r1]})
    obj, hyp, dist = region_frames(tracks, truth, rg)
    assert obj.height == 10 and hyp.height == 9  # no hypothesis before the track's first row
    assert dist.sort("t")["distance"].to_list() == [0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0]
    m = mot_metrics(obj, hyp, dist, gate=1.0)
    assert m["misses"] == 1 and m["mota"] == pytest.approx(0.9) and m["motp"] == pytest.approx(1 / 9)
