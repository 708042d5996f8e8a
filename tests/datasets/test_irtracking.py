"""``onebit import irtracking``: a dataset folder from the ceiling array's files."""

from __future__ import annotations

import re
import tomllib

import networkx as nx
import polars as pl
import pytest

from onebit.cli import main
from onebit.core.errors import InputError
from onebit.core.site import load_site
from onebit.core.tables import CROSSINGS, MOTION
from onebit.datasets.irtracking import DEFAULT_TARGETS, import_irtracking
from onebit.datasets.irtracking_sim import write_irtracking
from onebit.pipeline.context import RunContext
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline
from onebit.pipeline.stages import TRACKERS
from onebit.pipeline.tracking import tracker_inputs


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    return write_irtracking(tmp_path_factory.mktemp("irt") / "data", frames=30, people=3, seed=1)


def test_import_writes_site_frames_truth(files, tmp_path):
    out = tmp_path / "ds"
    assert (
        main(["import", "irtracking", str(files.readings), str(out), "--truth", str(files.truth), "--radius", "0.8"])
        == 0
    )
    site = load_site(out / "site.toml")
    n = len(files.sensors_mm)
    assert len(site.binary_sensors) == n and {m.id for m in site.motion_sensors} == {
        p.id for p in site.proximity_sensors
    }
    assert site.level_sensors == frozenset(str(i) for i in range(1, n + 1))
    assert site.binary_sensors[0].position == pytest.approx(tuple(files.sensors_mm[0] / 1000))
    assert site.binary_sensors[0].r_outer == 0.8
    assert site.targets == DEFAULT_TARGETS  # never the truth's count (3)
    assert site.boundary.bounds == (0.0, 0.0, 8.0, 14.0)
    g = site.sensor_graph  # from the geometry: the smallest distance that keeps the array connected (a 1.5 m grid here)
    assert len(g.nodes) == n and len(g.edges) > 0 and all(a in g.nodes and b in g.nodes for a, b in g.edges)
    assert nx.is_connected(g.to_networkx())
    frames = pl.read_csv(out / "frames.csv", schema_overrides={"active": pl.String})
    assert frames["t"].to_list() == [0.5 * k for k in range(30)]
    for k, row in enumerate(frames.iter_rows(named=True), start=1):
        assert sorted(int(s) for s in (row["active"] or "").split()) == files.active[k]
    truth = pl.read_csv(out / "truth.csv", schema_overrides={"target": pl.String})
    assert truth.height == sum(len(v) for v in files.truth_mm.values())
    last = truth.filter(t=14.5, target="2").row(0, named=True)
    assert (last["x"], last["y"]) == pytest.approx(tuple(v / 1000 for v in files.truth_mm[30][2]), abs=1e-4)
    info = tomllib.loads((out / "import.toml").read_text())
    assert info["counts"]["frames"] == 30 and info["counts"]["rejected"] == 0


def test_detections_xml_gives_the_same_frames(files, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    import_irtracking(files.readings, a)
    import_irtracking(files.detections, b, targets=3)
    assert (a / "frames.csv").read_text() == (b / "frames.csv").read_text()
    assert load_site(b / "site.toml").targets == 3


def test_detection_far_from_every_sensor_is_rejected(files, tmp_path):
    text = files.detections.read_text()
    bad = tmp_path / "bad.xml"
    bad.write_text(re.sub(r'xc="[^"]*" yc="[^"]*"', 'xc="9999" yc="9999"', text, count=1))
    res = import_irtracking(bad, tmp_path / "ds", coordinates=files.coordinates)
    assert res.info["counts"]["rejected"] == 1
    rej = pl.read_csv(tmp_path / "ds" / "rejects.csv")
    assert "not within 100.0 mm of a sensor" in rej["reason"][0] and rej["line"][0] > 0


def test_missing_coordinates_and_bad_options(tmp_path, files):
    lone = tmp_path / "x" / "y" / "z" / "s.txt"
    lone.parent.mkdir(parents=True)
    lone.write_bytes(files.readings.read_bytes())
    with pytest.raises(InputError, match="getSensorCoordinates.m"):
        import_irtracking(lone, tmp_path / "ds")
    with pytest.raises(InputError, match="field 'targets'"):
        import_irtracking(files.readings, tmp_path / "ds", targets=0)
    with pytest.raises(InputError, match="field 'r_inner'"):
        import_irtracking(files.readings, tmp_path / "ds", radius=1.0, r_inner=2.0)


def test_imported_dataset_runs_from_its_frame_log(files, tmp_path):
    """The frames stage serves every tracker's tables from frames.csv: levels at every frame,
    motion edges and proximity frames of the binary sensors declared once."""
    ds = tmp_path / "ds"
    import_irtracking(files.readings, ds, truth=files.truth, radius=0.8, targets=3)
    res = run_pipeline(ds, tmp_path / "run", trackers=["istate"], rrd=False)
    assert res.status["frames"].startswith("ok") and res.status["motion"].startswith("skipped")
    lv = pl.read_parquet(tmp_path / "run" / "tables" / "levels.parquet")
    n = len(files.sensors_mm)
    assert lv.height == 30 * n and int(lv["on"].sum()) == sum(len(v) for v in files.active.values())
    pf = pl.read_parquet(tmp_path / "run" / "tables" / "proximity_frames.parquet")
    assert pf.height == lv.height
    assert metric(res.report, "frames/frames") == 30 and metric(res.report, "frames/rejected") == 0
    assert res.status["istate"].startswith("ok")


def test_a_frame_log_reaches_the_trackers_through_their_tables(files, tmp_path):
    """A frame log's readings reach a tracker through the tables it reads (``proximity_frames``);
    ``levels`` is read by no tracker and handed to none; the proximity stage says why it skipped."""
    ds = tmp_path / "ds"
    import_irtracking(files.readings, ds, radius=0.8, targets=3)
    res = run_pipeline(ds, tmp_path / "run", trackers=["istate"], rrd=False)
    assert res.status["proximity"].startswith("skipped") and "frame log" in res.status["proximity"]
    site = load_site(ds / "site.toml")
    lv = pl.read_parquet(tmp_path / "run" / "tables" / "levels.parquet")
    tables = {
        "levels": lv,
        "motion": pl.DataFrame(schema=MOTION),
        "proximity_frames": lv,
        "crossings": pl.DataFrame(schema=CROSSINGS),
    }
    ctx = RunContext(ds, tmp_path / "x", site, None, {}, tables=tables)
    for entry in TRACKERS:
        inputs = tracker_inputs(entry, ctx)
        assert "levels" not in inputs, entry.name
        if "proximity_frames" in entry.spec.needs:
            assert inputs["proximity_frames"] is lv, entry.name


def test_a_frame_log_in_mcap_reads_as_the_csv(files, tmp_path):
    """``onebit logs convert`` puts frames.csv on the /frames channel; a run reads the same levels."""
    ds = tmp_path / "ds"
    import_irtracking(files.readings, ds, truth=files.truth, radius=0.8, targets=3)
    mc = tmp_path / "mc"
    mc.mkdir()
    (mc / "site.toml").write_text((ds / "site.toml").read_text())
    assert main(["logs", "convert", str(ds), str(mc / "recording.mcap")]) == 0
    run_pipeline(ds, tmp_path / "run-csv", trackers=["istate"], rrd=False)
    b = run_pipeline(mc, tmp_path / "run-mcap", trackers=["istate"], rrd=False)
    assert b.status["frames"].startswith("ok") and b.status["motion"].startswith("skipped")
    la = pl.read_parquet(tmp_path / "run-csv" / "tables" / "levels.parquet")
    lb = pl.read_parquet(tmp_path / "run-mcap" / "tables" / "levels.parquet")
    assert la.equals(lb)
