"""The home tab: a run of a small ARAS-format house (one day) opens on "home", whose count plot
spans the whole run, and the count and its truth are recorded as step series over the whole run.

The house is written here: a README with the sensor table and one day file of 86 400 rows (the
house door opened as one resident goes out from 30 000 s to 40 000 s and comes back; the couch
and the bed used around it).
"""

from __future__ import annotations

import numpy as np
import pytest
import rerun as rr
import rerun.blueprint as rrb

from onebit.datasets.aras import import_aras
from onebit.pipeline.runner import run_pipeline
from onebit.pipeline.stages import LOOKS
from onebit.viz import inspect as rrd
from onebit.viz.blueprint import BLUEPRINT_FILE, HOME_TAB, Logged, make_blueprint
from onebit.viz.occupancy import DOOR_Y

README = """SENSOR EXPLANATIONS (In column order)
Column\tSensor ID\tSensor Type\t\t\tPlace
1\t\tCo1\t\tContact Sensor\t\tHouse door
2\t\tIr1\t\tIR\t\t\tCouch
3\t\tFo1\t\tForce Sensor\t\tBed
4\t\tPh1\t\tPhotocell\t\tKitchen cupboard
5\t\tTe1\t\tTemperature\t\tKitchen

ACTIVITY EXPLANATIONS
ID\tACTIVITY
1\tOther
2\tGoing Out
"""
DAY_S = 86_400
OUT_AT, BACK_AT = 30_000, 40_000


def _house(folder):
    folder.mkdir()
    (folder / "README").write_text(README)
    levels = np.zeros((DAY_S, 5), dtype=np.int64)
    levels[:, 4] = 1  # the temperature sensor: not a person sensor
    for t0 in (OUT_AT - 5, BACK_AT):  # the door opened on the way out and back
        levels[t0 : t0 + 4, 0] = 1
    for t0 in range(600, DAY_S - 600, 1800):  # the couch and the cupboard through the day
        levels[t0 : t0 + 30, 1] = 1
        levels[t0 + 300 : t0 + 320, 3] = 1
    levels[:20_000, 2] = 1  # in bed until morning
    acts = np.ones((DAY_S, 2), dtype=np.int64)
    acts[OUT_AT:BACK_AT, 1] = 2  # resident 2 goes out
    np.savetxt(folder / "DAY_1.txt", np.c_[levels, acts], fmt="%d", delimiter=" ")
    return folder


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    root = tmp_path_factory.mktemp("home")
    import_aras(_house(root / "house"), root / "ds")
    res = run_pipeline(root / "ds", root / "out", trackers=("residents",), progress=False)
    assert res.ok, res.status
    folder = res.out / "rrd"
    return folder, sorted(p for p in folder.glob("*.rrd") if not p.name.startswith("_"))


def test_the_run_opens_on_the_home_tab(run):
    folder, files = run
    tabs = rrd.blueprint_tabs(folder / BLUEPRINT_FILE)
    assert tabs[0] == HOME_TAB, tabs
    assert any(t.startswith("residents: ") for t in tabs), tabs
    views = rrd.blueprint_views(folder / BLUEPRINT_FILE)
    home_map = next(v for v in views if v.name.startswith("home ("))
    for entity in ("occupancy/sensors", "residents/tracks/person1"):
        assert rrd.query_includes(home_map.query, entity, origin=home_map.origin), (entity, home_map.query)
    count = next(v for v in views if v.name.startswith("people home"))
    for entity in ("occupancy/present", "occupancy/truth", "occupancy/doors"):
        assert rrd.query_includes(count.query, entity, origin=count.origin), entity


def test_the_count_plot_spans_the_whole_run(run):
    folder, files = run
    logged = Logged(rrd.entity_archetypes(files), rrd.scalar_ranges(files))
    blueprint = make_blueprint(logged, looks=LOOKS)
    home = blueprint.root_container.contents[0]
    assert home.name == HOME_TAB

    def views(c):
        for x in c.contents:
            yield from [x] if isinstance(x, rrb.View) else views(x)

    plot = next(v for v in views(home) if v.class_identifier == "TimeSeries")
    ranges = plot.properties["VisibleTimeRanges"].ranges.as_arrow_array().to_pylist()
    assert ranges == [{"timeline": "t", "range": {"start": None, "end": None}}]  # both ends unbounded
    axis = plot.properties["TimeAxis"]
    assert axis.view_range.as_arrow_array().to_pylist() == [{"start": None, "end": None}]
    # the same in the file the viewer opens
    found = []
    reader = rrd._reader(folder / BLUEPRINT_FILE)
    for chunk in reader.stream(store=reader.blueprints()[0]):
        rb = chunk.to_record_batch()
        if chunk.entity_path.endswith("/VisibleTimeRanges") and "VisibleTimeRanges:ranges" in rb.schema.names:
            found += rb.column("VisibleTimeRanges:ranges").to_pylist()
    assert [{"timeline": "t", "range": {"start": None, "end": None}}] in found


def test_the_count_and_truth_are_steps_over_the_whole_run(run):
    _, files = run
    occ = [f for f in files if f.name == "occupancy.rrd"]
    assert occ, files
    for entity in ("occupancy/present", "occupancy/truth"):
        modes = rrd.component_rows(occ, entity, "SeriesLines:interpolation_mode")
        step = rr.components.InterpolationMode.StepAfter.value
        assert modes and all(m == [step] for m in modes), (entity, modes)
        rows = rrd.timed_rows(occ, entity, "Scalars:scalars")
        ts = [t for t, _ in rows]
        assert ts[0] <= 600 and ts[-1] >= DAY_S - 60, (entity, ts[:3], ts[-3:])
    truth = [(t, v[0]) for t, v in rrd.timed_rows(occ, "occupancy/truth", "Scalars:scalars")]
    assert (OUT_AT, 1.0) in truth and (BACK_AT, 2.0) in truth, truth
    doors = rrd.timed_rows(occ, "occupancy/doors", "Scalars:scalars")
    assert doors and all(v == [DOOR_Y] for _, v in doors)
    assert any(abs(t - OUT_AT) <= 60 for t, _ in doors) and any(abs(t - BACK_AT) <= 60 for t, _ in doors)


def test_the_sensors_are_labelled_and_lit(run):
    _, files = run
    labels = rrd.component_rows(files, "occupancy/sensors", "Points2D:labels")
    assert labels and sorted(labels[0]) == ["Co1", "Fo1", "Ir1", "Ph1"], labels[:1]  # not the temperature
    shown = rrd.component_rows(files, "occupancy/sensors", "Points2D:show_labels")
    assert shown and shown[0] == [True]
    rgba = rrd.timed_rows(files, "occupancy/sensors", "Points2D:colors")
    assert len({tuple(v) for _, v in rgba}) > 1  # the colours change as sensors go on and off
    residents_map = [
        v for v in rrd.blueprint_views(files[0].parent / BLUEPRINT_FILE) if v.name.startswith("people and the events")
    ]
    assert residents_map  # the residents map shows the sensor marks (labels on: an override)
    assert "site/sensors" in residents_map[0].overrides
