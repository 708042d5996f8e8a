"""The summary tab (onebit.viz.blueprint.Planner.summary) and the series it shows: every
tracker's people present as steps (onebit.viz.occupancy.log_people) and the truth's
(onebit.viz.occupancy.truth_people_steps)."""

from __future__ import annotations

import polars as pl
import rerun as rr
import rerun.blueprint as rrb

from onebit.pipeline.stages import LOOKS
from onebit.viz import inspect as rrd
from onebit.viz.blueprint import SUMMARY_TAB, Logged, make_blueprint
from onebit.viz.occupancy import log_people, log_truth_people, truth_people_steps
from onebit.viz.recording import close_recording, open_recording

WHOLE_RUN = [{"timeline": "t", "range": {"start": None, "end": None}}]


def _views(container):
    for x in container.contents:
        yield from [x] if isinstance(x, rrb.View) else _views(x)


def test_the_truths_people_present_counts_each_target_from_its_first_to_its_last_row():
    truth = pl.DataFrame(
        {"t": [0.0, 4.0, 10.0, 5.0, 20.0, 10.0], "target": ["a", "a", "a", "b", "b", "c"], "x": [0.0] * 6}
    )
    t, v = truth_people_steps(truth)
    # c is seen once at 10 s, as a ends: in and out at the same time
    assert t.tolist() == [0.0, 5.0, 10.0, 20.0]
    assert v.tolist() == [1.0, 2.0, 1.0, 0.0]
    assert truth_people_steps(None)[0].size == 0
    assert truth_people_steps(truth.head(0))[0].size == 0


def test_people_are_logged_as_steps_and_not_averaged(tmp_path):
    path = tmp_path / "people.rrd"
    rec = open_recording(path, recording_id="r")
    log_people(rec, "beams", pl.DataFrame({"t": [0.0, 3.0, 7.0], "present": [0, 2, 1]}), rgb=(10, 20, 30))
    log_people(rec, "empty", pl.DataFrame({"t": [], "present": []}, schema={"t": pl.Float64, "present": pl.Int64}))
    log_truth_people(rec, pl.DataFrame({"t": [1.0, 9.0], "target": ["a", "a"]}))
    close_recording(rec, path)
    files = [path]
    assert "empty/people" not in rrd.entity_paths(path)
    for entity in ("beams/people", "summary/truth"):
        modes = rrd.component_rows(files, entity, "SeriesLines:interpolation_mode")
        assert modes == [[rr.components.InterpolationMode.StepAfter.value]], (entity, modes)
        policy = rrd.component_rows(files, entity, "SeriesLines:aggregation_policy")
        assert policy == [[rr.components.AggregationPolicy.Off.value]], (entity, policy)
    assert [(t, v) for t, v in rrd.timed_rows(files, "beams/people", "Scalars:scalars")] == [
        (0.0, [0.0]),
        (3.0, [2.0]),
        (7.0, [1.0]),
    ]
    assert rrd.component_rows(files, "beams/people", "SeriesLines:names") == [["beams: people"]]


def test_the_summary_tab_shows_every_count_and_error_over_the_whole_run():
    logged = {
        "site": {"Transform3D"},
        "site/boundary": {"LineStrips2D"},
        "beams": {"Transform3D"},
        "beams/tracks/1": {"Points2D"},
        "beams/people": {"Scalars", "SeriesLines"},
        "istate/people": {"Scalars", "SeriesLines"},
        "summary/truth": {"Scalars", "SeriesLines"},
        "scores/beams/1": {"Scalars", "SeriesLines"},
        "scores/istate/1": {"Scalars", "SeriesLines"},
        "sensors/a": {"StateChange"},
        "sensors/a/log": {"TextLog"},
    }
    blueprint = make_blueprint(Logged(logged, {"beams/people": (0.0, 2.0)}), units="ft", looks=LOOKS)
    tabs = blueprint.root_container.contents
    assert tabs[-1].name == SUMMARY_TAB and [t.name for t in tabs].count(SUMMARY_TAB) == 1
    views = {v.name: v for v in _views(tabs[-1])}
    count = views["people present: each tracker vs the truth over the run (count)"]
    assert list(count.contents) == ["+ summary/truth", "+ beams/people", "+ istate/people"]  # the truth drawn first
    assert "beams: error of each track over the run (hops)" in views
    assert "istate: error of each track over the run (ft)" in views
    assert "events: sensors on / off over the run" in views
    for v in views.values():
        if v.class_identifier in ("TimeSeries", "StateTimeline"):
            assert v.properties["VisibleTimeRanges"].ranges.as_arrow_array().to_pylist() == WHOLE_RUN, v.name
            assert v.properties["TimeAxis"].view_range.as_arrow_array().to_pylist() == [{"start": None, "end": None}]
    assert "more" not in [t.name for t in tabs]  # summary/truth is placed


def test_no_summary_without_a_tracker():
    blueprint = make_blueprint({"site": {"Transform3D"}, "site/boundary": {"LineStrips2D"}})
    assert SUMMARY_TAB not in [t.name for t in blueprint.root_container.contents]
