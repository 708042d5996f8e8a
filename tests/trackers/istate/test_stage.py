"""The ``istate`` tracker stage: end to end on the ``istate-room`` scenario, and run() on
motion, proximity and crossing tables directly."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest
import shapely

from onebit._testing.oracles import istate_filter_reference
from onebit.core.config import config_from_mapping
from onebit.core.errors import ConfigError
from onebit.core.site import load_site, site_from_dict
from onebit.core.tables import TRACKS
from onebit.datasets.okane_sim import write_room_dataset
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline
from onebit.scoring.istate import score
from onebit.trackers.istate import SPEC
from onebit.trackers.istate.core import IState, contains
from onebit.trackers.istate.stage import IStateConfig, run
from onebit.viz.inspect import entity_paths, verify


@pytest.fixture(scope="module")
def room_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("istate")
    data = write_room_dataset(root / "data", seed=4, duration=90.0, n=2)
    res = run_pipeline(data, root / "run", trackers=("istate",), config={"istate": {"max_elements": 6}})
    return data, res


def test_pipeline_containment_is_one_without_false_positives(room_run):
    _, res = room_run
    assert res.ok, res.status
    rep = res.report
    assert metric(rep, "istate/containment") == 1.0
    assert metric(rep, "istate/scored_stages") >= 80
    assert 1.0 <= metric(rep, "istate/elements_mean") <= metric(rep, "istate/elements_max") <= 6
    # knowledge narrower than the whole free space (2 copies of ~91 m^2 would be W^2)
    site = load_site(res.out.parent / "data" / "site.toml")
    assert 0 < metric(rep, "istate/area_mean") < site.free_space.area
    assert metric(rep, "motion/edges") > 0  # the motion reader fed the tracker


def test_pipeline_tables_and_recording(room_run):
    _, res = room_run
    tables = res.out / "tables"
    tracks = pl.read_parquet(tables / "istate_tracks.parquet")
    assert tracks.schema == TRACKS
    for name in ("istate_summary", "istate_regions", "istate_detections", "istate_containment"):
        assert (tables / f"{name}.parquet").exists(), name
    rrd = res.out / "rrd" / "istate.rrd"
    verify(rrd)
    ents = entity_paths(rrd)
    assert {"istate/elements", "istate/area", "istate/istate/0/0", "istate/istate/0/1", "istate/sensing/m1"} <= ents


def _room_tables(seed: int, n: int, drop: float, tmp_path):
    data = write_room_dataset(tmp_path / f"d{seed}", seed=seed, duration=60.0, n=n, drop=drop)
    site = load_site(data / "site.toml")
    raw = pl.read_csv(data / "motion.csv")
    motion = raw.select(pl.col("t").cast(pl.Float64), "sensor", on=pl.col("value") == 1)
    return site, motion, pl.read_csv(data / "truth.csv")


@pytest.mark.parametrize("shape,negatives,drop", [("exact", False, 0.3), ("rect", True, 0.0), ("disk", False, 0.0)])
def test_run_direct_containment_with_false_negatives(tmp_path, shape, negatives, drop):
    site, motion, truth = _room_tables(7, 3, drop, tmp_path)
    cfg = IStateConfig(shape=shape, reliable_negatives=negatives, max_elements=5)
    out = run({"motion": motion}, site, cfg)
    rows, tables = score(
        "istate", {"istate_summary": out["summary"], "istate_regions": out["regions"], "truth": truth}, site
    )
    m = {r[1]: r[2] for r in rows}
    assert m["containment"] == 1.0 and m["scored_stages"] > 50
    assert m["elements_max"] <= 5
    # every stage's I-state really contains the truth (recomputed, independent of score())
    regs = out["regions"]
    k = int(out["summary"]["stage"][len(out["summary"]) // 2])
    tk = float(out["summary"]["t"][k])
    g = shapely.from_wkb(regs.filter(pl.col("stage") == k)["wkb"].to_numpy()).reshape(-1, 3)
    x = truth.filter((pl.col("t") - tk).abs() < 1e-6).sort("target").select("x", "y").to_numpy()
    assert contains(IState(g), x)


def test_proximity_and_crossings_as_sensing_regions():
    """A corridor with a beam and two proximity sensors; one target walks through."""
    site = site_from_dict(
        {
            "boundary": {"polygon": [[0, 0], [20, 0], [20, 4], [0, 4]]},
            "beams": [{"id": "b", "segment": [[10, 0], [10, 4]], "forward": "left", "spacing": 0.1}],
            "proximity_sensors": [
                {"id": "p1", "position": [4, 2], "radius": 1.5},
                {"id": "p2", "position": [16, 2], "r_inner": 1.0, "r_outer": 2.0},
            ],
            "targets": 1,
        }
    )
    t = np.arange(0, 20.01, 0.1)
    xy = np.column_stack([1 + 0.9 * t, np.full(len(t), 2.0)])
    truth = pl.DataFrame({"t": t, "target": "a", "x": xy[:, 0], "y": xy[:, 1]})
    d1 = np.hypot(xy[:, 0] - 4, 0) <= 1.5
    d2 = np.hypot(xy[:, 0] - 16, 0) <= 2.0
    edges = []
    for sid, on in (("p1", d1), ("p2", d2)):
        ch = np.flatnonzero(np.diff(np.r_[False, on].astype(int)) != 0)
        edges.append(pl.DataFrame({"t": t[ch], "sensor": sid, "on": on[ch]}))
    prox = pl.concat(edges).sort("t")
    t_cross = (10 - 1) / 0.9
    crossings = pl.DataFrame(
        {"t": [t_cross], "beam": ["b"], "direction": [1]},
        schema={"t": pl.Float64, "beam": pl.String, "direction": pl.Int8},
    )
    out = run({"proximity": prox, "crossings": crossings}, site, IStateConfig(max_speed=1.0, reliable_negatives=True))
    rows, _ = score(
        "istate", {"istate_summary": out["summary"], "istate_regions": out["regions"], "truth": truth}, site
    )
    m = {r[1]: r[2] for r in rows}
    assert m["containment"] == 1.0
    det = out["detections"]
    assert set(det["sensor"]) == {"p1", "p2", "b"}
    # right after the crossing the target is pinned near the beam: a small region
    k = int(np.ceil(t_cross))
    after = out["summary"].filter(pl.col("t") == float(k))
    assert after["area"][0] < 0.15 * site.free_space.area


def test_level_sampled_readings_use_the_log_resolution_as_latency():
    """Readings of every sensor at whole seconds (not edges): the off reading comes up to 1 s
    after the target left, and the automatic latency (the log's 1 s resolution) keeps the
    truth inside; a zero latency does not."""
    site = site_from_dict(
        {
            "boundary": {"polygon": [[0, 0], [12, 0], [12, 3], [0, 3]]},
            "proximity_sensors": [{"id": f"p{i}", "position": [1.5 + 3 * i, 1.5], "radius": 1.0} for i in range(4)],
            "targets": 1,
        }
    )
    t = np.arange(0.0, 12.0, 1.0)
    x = 0.35 + 0.97 * t
    truth = pl.DataFrame({"t": t, "target": "a", "x": x, "y": np.full(len(t), 1.5)})
    sensors = [f"p{i}" for i in range(4)]
    on = np.abs(x[:, None] - (1.5 + 3 * np.arange(4))[None, :]) <= 1.0
    levels = pl.DataFrame({"t": np.repeat(t, 4), "sensor": sensors * len(t), "on": on.ravel()})
    got = {}
    for auto in (True, False):
        out = run({"proximity": levels}, site, IStateConfig(max_speed=1.0, latency_auto=auto, shape="rect"))
        rows, _ = score(
            "istate", {"istate_summary": out["summary"], "istate_regions": out["regions"], "truth": truth}, site
        )
        got[auto] = {r[1]: r[2] for r in rows}["containment"]
    assert got[True] == 1.0 and got[False] < 1.0


def test_config_validation_names_the_field():
    with pytest.raises(ConfigError, match="shape"):
        IStateConfig(shape="hexagon")
    with pytest.raises(ConfigError, match="period_s"):
        IStateConfig(period_s=0)
    with pytest.raises(ConfigError, match="unknown field"):
        config_from_mapping(IStateConfig, {"M": 3}, section="istate")


def _corridor():
    return {
        "boundary": {"polygon": [[0, 0], [5, 0], [5, 5], [0, 5]]},
        "proximity_sensors": [{"id": "p", "position": [2, 2], "radius": 1}],
    }


def test_unknown_target_count_is_an_error():
    site = site_from_dict(
        {
            "boundary": {"polygon": [[0, 0], [5, 0], [5, 5], [0, 5]]},
            "proximity_sensors": [{"id": "p", "position": [2, 2], "radius": 1}],
        }
    )
    with pytest.raises(ConfigError, match="targets"):
        run({}, site, IStateConfig())
    assert "number of targets" in SPEC.available(site)
    assert SPEC.available(site_from_dict({**_corridor(), "targets": 1})) is None
    bare = site_from_dict({"boundary": {"polygon": [[0, 0], [5, 0], [5, 5], [0, 5]]}})
    assert "no binary sensors" in SPEC.available(bare)


def test_deterministic_and_empty_input(tmp_path):
    site, motion, _ = _room_tables(2, 2, 0.0, tmp_path)
    a = run({"motion": motion}, site, IStateConfig())
    b = run({"motion": motion}, site, IStateConfig())
    assert a["summary"].equals(b["summary"]) and a["regions"].equals(b["regions"])
    empty = run({"motion": motion.clear()}, site, IStateConfig())
    assert empty["tracks"].height == 0 and empty["summary"].height == 0


def test_regions_table_is_the_stages_rows_in_order():
    """The run's regions table built at once equals one frame per stage, concatenated (stages
    with no element included), each region mapped from the filter's frame to site units
    (``x L + origin``; a region object recurring across stages mapped once, the same rows)."""
    from onebit.trackers.istate.core import SiteFrame
    from onebit.trackers.istate.stage import REGIONS, _regions_table

    rng = np.random.default_rng(0)
    n = 2
    times = np.array([0.0, 1.0, 2.0, 3.0])
    stages = [
        np.array([shapely.box(*rng.uniform(0, 1, 2), *rng.uniform(2, 3, 2)) for _ in range(E * n)], dtype=object)
        for E in (1, 0, 3, 2)
    ]
    stages[3][1] = stages[2][4]  # the same region object in two stages
    frame = SiteFrame((2.0, -1.0), 4.0)
    to_site = lambda g: shapely.affinity.affine_transform(g, [4.0, 0, 0, 4.0, 2.0, -1.0])  # noqa: E731
    site = [np.array([to_site(g) for g in r] + [None], dtype=object)[:-1] for r in stages]
    frames = [
        pl.DataFrame(
            {
                "t": np.full(len(r), tk),
                "stage": np.full(len(r), k, dtype=np.int64),
                "element": np.repeat(np.arange(len(r) // n, dtype=np.int64), n),
                "k": np.tile(np.arange(n, dtype=np.int64), len(r) // n),
                "area": shapely.area(r),
                "wkb": shapely.to_wkb(r),
            },
            schema=REGIONS,
        )
        for k, (tk, r) in enumerate(zip(times, site))
    ]
    assert _regions_table(times, stages, n, frame).equals(pl.concat(frames))
    assert _regions_table(times[:1], [stages[1]], n, frame).equals(frames[1].clear())
    assert _regions_table(times[:0], [], n, frame).equals(pl.DataFrame(schema=REGIONS))
    # I-states laid out once and named per stage: the table of the stages' own arrays
    states, of_stage = [stages[2], stages[1], stages[3]], np.array([2, 0, 0, 1])
    per_stage = [states[s] for s in of_stage]
    assert _regions_table(times, states, n, frame, of_stage).equals(_regions_table(times, per_stage, n, frame))
    assert _regions_table(times, states, n, frame, of_stage)["stage"].to_list() == [0, 0, 0, 0] + [1] * 6 + [2] * 6
    from onebit.trackers.istate import stage as st

    whole = _regions_table(times, stages, n, frame)
    st.REGIONS_CHUNK, chunk = 1, st.REGIONS_CHUNK  # a stage at a time: the same table
    try:
        assert _regions_table(times, stages, n, frame).equals(whole)
    finally:
        st.REGIONS_CHUNK = chunk


@pytest.mark.parametrize("shape", ["exact", "rect", "disk"])
def test_the_stage_is_unit_free(tmp_path, shape):
    """The same room in cm gives the results in m scaled, to round-off (the filter runs in the
    site's normalised frame, the same numbers in every unit): element counts per stage,
    areas times 10^4, the point summary and every region times 100."""
    import tomllib

    from onebit.core.units import config_in_site_units
    from tests.pipeline.test_units import site_in_cm

    data = write_room_dataset(tmp_path / "d", seed=5, duration=40.0, n=3)
    raw = pl.read_csv(data / "motion.csv")
    motion = raw.select(pl.col("t").cast(pl.Float64), "sensor", on=pl.col("value") == 1)
    site_m = load_site(data / "site.toml")
    cm, k = site_in_cm(tomllib.loads((data / "site.toml").read_text()))
    site_cm = site_from_dict(cm)
    cfg = IStateConfig(shape=shape, max_elements=4, reliable_negatives=shape == "rect")
    a = run({"motion": motion}, site_m, cfg)
    b = run({"motion": motion}, site_cm, config_in_site_units(cfg, site_cm))
    sa, sb = a["summary"], b["summary"]
    assert sa["elements"].to_list() == sb["elements"].to_list() and sa["elements"].max() > 1
    assert np.allclose(sb["area"].to_numpy(), sa["area"].to_numpy() * k * k, rtol=1e-12, atol=0)
    for c in ("x", "y"):
        assert np.allclose(b["tracks"][c].to_numpy() / k, a["tracks"][c].to_numpy(), rtol=0, atol=1e-12, equal_nan=True)
    ga = shapely.from_wkb(a["regions"]["wkb"].to_numpy())
    gb = shapely.transform(shapely.from_wkb(b["regions"]["wkb"].to_numpy()), lambda xy: xy / k)
    assert (shapely.get_num_coordinates(ga) == shapely.get_num_coordinates(gb)).all()
    assert np.allclose(shapely.get_coordinates(ga), shapely.get_coordinates(gb), rtol=0, atol=1e-12)


def _tiled_room(tmp_path, n: int, copies: int = 3, span: float = 30.0):
    """A room's motion log of ``span`` s repeated ``copies`` times (offsets of whole stages):
    its readings, and so its stage transitions, recur."""
    data = write_room_dataset(tmp_path / "tiled", seed=3, duration=span, n=n)
    raw = pl.read_csv(data / "motion.csv")
    motion = raw.select(pl.col("t").cast(pl.Float64), "sensor", on=pl.col("value") == 1)
    tiles = [motion.with_columns(pl.col("t") + i * (span + 10.0)) for i in range(copies)]
    return load_site(data / "site.toml"), pl.concat(tiles)


@pytest.mark.parametrize(
    "cfg",
    [
        IStateConfig(max_elements=4),
        IStateConfig(shape="rect", reliable_negatives=True, max_elements=3),
        IStateConfig(shape="disk", contradictions="empty", max_speed=0.5),
        IStateConfig(max_elements=0, substeps=2, absent_after=3.0),
    ],
)
def test_transitions_looked_up_equal_every_stage_computed(tmp_path, monkeypatch, cfg):
    """The stage loop that looks up recurring transitions (:func:`_filter`) gives every table
    of the plain loop (:func:`onebit._testing.oracles.istate_filter_reference`), bit for bit -- also when its cache is
    dropped every few entries; and it does look stages up (fewer filter steps computed)."""
    from onebit.trackers.istate import stage as st

    site, motion = _tiled_room(tmp_path, n=2)
    calls = {"n": 0}
    update = st.info_state_update

    def counted(*a, **kw):
        calls["n"] += 1
        return update(*a, **kw)

    monkeypatch.setattr(st, "info_state_update", counted)
    fast = run({"motion": motion}, site, cfg)
    computed = calls["n"]
    stages = fast["summary"].height
    assert stages > 100 and computed < stages  # the quiet gaps and the repeated tiles are looked up
    with monkeypatch.context() as m:
        m.setattr(st, "TRANSITIONS_CAPACITY", 7)
        small = run({"motion": motion}, site, cfg)
        m.setattr(st, "_filter", istate_filter_reference)
        plain = run({"motion": motion}, site, cfg)
    for name in ("summary", "regions", "tracks", "detections"):
        assert fast[name].equals(plain[name]), name
        assert small[name].equals(plain[name]), name
    assert plain["summary"]["elements"].max() >= 1


def test_transitions_are_keyed_by_the_negatives_too():
    """Stages with the same I-state and the same reading 1 but a different reading 0 (a
    reliable negative) are different transitions: the looked-up loop equals the plain one."""
    from onebit.trackers.istate.stage import Stages, _filter

    free = shapely.box(0, 0, 1, 1)
    a, b = shapely.box(0, 0, 0.6, 1), shapely.box(0.3, 0, 1, 1)
    obj = lambda xs: np.array(xs + [None], dtype=object)[:-1]  # noqa: E731
    # stages 1-5 read a; stages 3 and 5 also clear b; the step (2) refills the square each stage
    stages = Stages(
        times=np.arange(6.0),
        detections=obj([a] * 5),
        det_bounds=np.array([0, 0, 1, 2, 3, 4, 5]),
        negatives=obj([b, b]),
        neg_bounds=np.array([0, 0, 0, 0, 1, 1, 2]),
        free=free,
        n=1,
        step=2.0,
    )
    cfg = IStateConfig(reliable_negatives=True)
    fast, plain = _filter(stages, cfg), istate_filter_reference(stages, cfg)
    areas = plain[2][:, 3]
    assert np.allclose(areas, [1.0, 0.6, 0.6, 0.3, 0.6, 0.3])
    assert np.array_equal(fast[2], plain[2]) and np.array_equal(fast[3], plain[3], equal_nan=True)
    per_stage = lambda out: [shapely.to_wkb(out[1][s]).tolist() for s in out[0]]  # noqa: E731
    assert per_stage(fast) == per_stage(plain)
    assert len(fast[1]) < len(stages.times)  # the recurring I-states are laid out once


def test_region_geometries_artifact_is_the_regions_table_parsed(tmp_path):
    """The geometries handed to the recording, row by row, are the regions table's WKB parsed:
    the same bytes, and one object per distinct WKB (as :func:`onebit.core.wkb.geometries`)."""
    from onebit.core.wkb import geometries

    site, motion = _tiled_room(tmp_path, n=2, copies=2)
    out = run({"motion": motion}, site, IStateConfig(max_elements=4))
    got = out["artifacts"]["region_geometries"]
    regs = out["regions"]
    assert len(got) == regs.height > 0
    assert shapely.to_wkb(got).tolist() == regs["wkb"].to_list()
    parsed = geometries(regs["wkb"])
    assert np.array_equal(_objects_in_order(got), _objects_in_order(parsed))


def _objects_in_order(geoms) -> np.ndarray:
    """Each row's object numbered in order of first appearance (equal for arrays that share
    objects at the same rows)."""
    _, first, inv = np.unique(np.fromiter(map(id, geoms), np.int64), return_index=True, return_inverse=True)
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first)] = np.arange(len(first))
    return rank[inv.ravel()]
