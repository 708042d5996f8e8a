"""onebit.viz.blueprint: the layout of a run, read back from the files a real run wrote.

For a short run of each demo scenario, the recordings (``OUT/rrd/*.rrd``) and the blueprint
(``OUT/rrd/blueprint.rbl``, and the same layout in ``OUT/rrd/_blueprint.rrd``) are read back:
every view names only logged entities, no view is empty, every logged entity is in a view, each
family opens on its own tab, trails are windowed and whole paths hidden, plots have one unit.
"""

from __future__ import annotations

import re

import pytest
import rerun as rr
import rerun.blueprint as rrb

from onebit.datasets.catalogue import get_scenario
from onebit.pipeline.runner import run_pipeline
from onebit.pipeline.stages import LOOKS, tracker_names
from onebit.viz import inspect as rrd
from onebit.viz.blueprint import (
    BLUEPRINT_FILE,
    BLUEPRINT_RECORDING,
    SUMMARY_TAB,
    Logged,
    make_blueprint,
    tracker_roots,
)
from onebit.viz.trails import TRAIL_S

#: Short versions of the demo's runs (Makefile ``demo``): scenario, options, the tab it opens on.
RUNS = {
    "beams-lab": ({"duration": 40.0, "agents": 2, "params": {}}, "beams: agents in regions"),
    "pir14": ({"duration": 40.0, "agents": None, "params": {"refractory": "4"}}, "intruder: particle filter"),
    "proximity-line": ({"duration": None, "agents": None, "params": {}}, "clustertrack: space-time"),
    "hallway": ({"duration": 30.0, "agents": 3, "params": {}}, "findinghumo: decoded paths"),
    "istate-room": ({"duration": 30.0, "agents": None, "params": {}}, "istate: I-state"),
}

TRACKER_NAMES = tracker_names()
VIEW_KIND = {"2D": "map", "TimeSeries": "series", "TextLog": "text", "StateTimeline": "state"}
DATA_OF = {
    "map": {"Points2D", "LineStrips2D", "Boxes2D", "Ellipses2D", "Arrows2D", "EncodedImage", "Image"},
    "series": {"Scalars"},
    "text": {"TextLog"},
    "state": {"StateChange"},
}


@pytest.fixture(scope="module", params=sorted(RUNS))
def run(request, tmp_path_factory):
    """``(name, rrd folder, logged kinds, views, trackers that ran)`` of a short run of one demo
    scenario."""
    name = request.param
    opts, _ = RUNS[name]
    root = tmp_path_factory.mktemp(name)
    data = get_scenario(name).write(root / "data", seed=7, drop=0.0, camera=False, **opts)
    res = run_pipeline(data, root / "out", progress=False)
    assert res.ok, res.status
    folder = res.out / "rrd"
    stages = sorted(p for p in folder.glob("*.rrd") if p.name != BLUEPRINT_RECORDING)
    ran = [t for t in TRACKER_NAMES if res.status.get(t, "").startswith("ok")]
    return name, folder, rrd.entity_archetypes(stages), rrd.blueprint_views(folder / BLUEPRINT_FILE), ran


def _included(view: rrd.ViewInfo, path: str) -> bool:
    return rrd.query_includes(view.query, path, origin=view.origin)


def test_views_name_only_logged_entities(run):
    _, _, logged, views, _ = run
    for v in views:
        for rule in rrd.query_rules(v.query, origin=v.origin):
            base = rrd.rule_base(rule)
            assert base in logged or any(p.startswith(base + "/") for p in logged), (v.name, rule)
        for entity in v.overrides:
            assert entity in logged and _included(v, entity), (v.name, entity)


def test_every_logged_entity_is_in_a_view(run):
    _, _, logged, views, _ = run
    missing = [p for p in logged if not any(_included(v, p) for v in views)]
    assert not missing, missing


def test_no_view_is_empty_and_each_shows_its_kind(run):
    _, _, logged, views, _ = run
    for v in views:
        kind = VIEW_KIND[v.kind]
        shown = [p for p in logged if _included(v, p)]
        assert any(logged[p] & DATA_OF[kind] for p in shown), (v.name, shown[:5])
        if kind != "map":  # a plot, a log or a state timeline holds only what it can draw
            assert all(logged[p] & DATA_OF[kind] for p in shown), (v.name, shown)


def test_each_family_opens_on_its_own_tab_and_nothing_is_left_over(run):
    """The run opens on its paper's tab; every tracker that ran has its family's tab (the HMM
    baselines one each, the room-centre baseline with the particle filter)."""
    name, folder, logged, _, ran = run
    tabs = rrd.blueprint_tabs(folder / BLUEPRINT_FILE)
    assert tabs[0] == RUNS[name][1], tabs
    for t in ran:
        owner = "intruder" if t == "intruder-naive" and "intruder" in ran else t
        assert sum(tab.startswith(f"{owner}: ") for tab in tabs) == 1, (t, tabs)
    home = int("home" in tabs)  # the occupancy stage ran (motion logs): its tab after the trackers'
    assert tabs[-1] == "summary"  # one per run, last
    assert len(tabs) == home + 1 + len(
        {("intruder" if t == "intruder-naive" and "intruder" in ran else t) for t in ran}
    )
    assert "more" not in tabs  # every entity found its family's view
    assert set(tracker_roots(Logged(logged), LOOKS)) <= set(ran)


def test_plots_say_what_and_in_which_unit(run):
    _, _, _, views, _ = run
    for v in views:
        assert v.name, v
        if v.kind == "TimeSeries":
            assert re.search(r"\((count|targets|hops|m|ft|m\u00b2|ft\u00b2)\)$", v.name), v.name
        if v.kind == "2D":
            assert re.search(r"\((m|ft)\)", v.name), v.name


def test_trails_move_with_the_cursor_and_whole_paths_are_hidden(run):
    _, _, logged, views, _ = run
    maps = [v for v in views if v.kind == "2D"]
    for p in logged:
        holders = [v for v in maps if _included(v, p)]
        if p.endswith("/trail"):
            assert holders and all(v.overrides.get(p, {}).get("time_range") == (-TRAIL_S, 0.0) for v in holders), p
        if p.endswith(("/path", "/regions", "/coverage")) or "/decoded/" in p:
            assert holders and all(v.overrides.get(p, {}).get("visible") is False for v in holders), p


def test_the_layout_is_sent_with_the_run(run):
    """``_blueprint.rrd``: a recording of the run (same ids) holding only the same layout."""
    _, folder, _, views, _ = run
    sent = folder / BLUEPRINT_RECORDING
    stage = next(p for p in sorted(folder.glob("*.rrd")) if p.name != BLUEPRINT_RECORDING)
    assert rrd.store_ids(sent) == rrd.store_ids(stage)
    assert rrd.entity_paths(sent) == set()
    assert sorted(v.name for v in rrd.blueprint_views(sent)) == sorted(v.name for v in views)


def test_estimates_are_named_tracks_and_truth_keeps_its_ids(run):
    _, folder, logged, _, _ = run
    files = sorted(folder.glob("*.rrd"))
    for p in logged:
        parts = p.split("/")
        if len(parts) == 3 and parts[1] == "tracks" and parts[0] not in ("camera",):
            (label,) = rrd.component_rows(files, p, "Points2D:labels")[0]
            assert re.fullmatch(r"track \d+|.+ estimate", label), (p, label)
        if len(parts) == 2 and parts[0] == "truth":
            assert rrd.component_rows(files, p, "Points2D:labels")[0] == [parts[1]]


def test_make_blueprint_without_data_and_with_an_unknown_tracker():
    empty = make_blueprint({})
    assert empty is not None
    logged = {
        "site": {"Transform3D"},
        "site/boundary": {"LineStrips2D"},
        "centroid": {"Transform3D"},
        "centroid/tracks/a": {"Points2D"},
        "scores/centroid/a": {"Scalars", "SeriesLines"},
        "odd/thing": {"TextLog"},
    }
    assert tracker_roots(Logged(logged)) == ["centroid", "odd"]
    with pytest.raises(ValueError, match="trail_s"):
        make_blueprint(logged, trail_s=0.0)


def _views(container):
    for x in container.contents:
        yield from [x] if isinstance(x, rrb.View) else _views(x)


WHOLE_RUN = [{"timeline": "t", "range": {"start": None, "end": None}}]


def test_the_summary_tab_shows_people_errors_and_events_over_the_whole_run(run):
    """One summary tab per run: every tracker's people present (with the truth when logged) and
    every tracker's error, each plot and the events' timeline over the whole run."""
    _, folder, logged, _, _ = run
    files = sorted(p for p in folder.glob("*.rrd") if p.name != BLUEPRINT_RECORDING)
    blueprint = make_blueprint(Logged(logged, rrd.scalar_ranges(files)), looks=LOOKS)
    (summary,) = [t for t in blueprint.root_container.contents if t.name == SUMMARY_TAB]
    views = list(_views(summary))
    entities = {e.removeprefix("+ ") for v in views for e in v.contents}
    people = {p for p in logged if p.endswith("/people") and "Scalars" in logged[p]}
    scores = {p for p in logged if p.startswith("scores/") and "Scalars" in logged[p]}
    assert people | scores, logged  # every demo run logs a count or an error
    assert people <= entities and scores <= entities, (people - entities, scores - entities)
    for v in views:
        if v.class_identifier in ("TimeSeries", "StateTimeline"):
            ranges = v.properties["VisibleTimeRanges"].ranges.as_arrow_array().to_pylist()
            assert ranges == WHOLE_RUN, (v.name, ranges)
            assert v.properties["TimeAxis"].view_range.as_arrow_array().to_pylist() == [{"start": None, "end": None}]


def test_every_trackers_people_is_a_step_series(run):
    """``<tracker>/people`` (every multi-person tracker's people table): steps, not averaged."""
    name, folder, logged, _, ran = run
    files = sorted(p for p in folder.glob("*.rrd") if p.name != BLUEPRINT_RECORDING)
    people = [p for p in logged if p.endswith("/people") and p.split("/")[0] in ran]
    if name in ("beams-lab", "istate-room", "proximity-line"):  # their trackers count people
        assert people, sorted(logged)
    for entity in people:
        modes = rrd.component_rows(files, entity, "SeriesLines:interpolation_mode")
        assert modes and all(m == [rr.components.InterpolationMode.StepAfter.value] for m in modes), entity
        policy = rrd.component_rows(files, entity, "SeriesLines:aggregation_policy")
        assert policy and all(p == [rr.components.AggregationPolicy.Off.value] for p in policy), entity
        assert len(rrd.timed_rows(files, entity, "Scalars:scalars")) >= 1
