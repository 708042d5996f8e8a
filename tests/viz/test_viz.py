"""onebit.viz: recordings are written atomically, verify, and hold the entity paths of docs/architecture.md."""

from __future__ import annotations

import subprocess

import numpy as np
import polars as pl
import pytest
import rerun as rr

from onebit.core import tables
from onebit.pipeline.stages import LOOKS
from onebit.viz import (
    color_of,
    colors_of,
    log_crossings,
    log_occupancy,
    log_point_tracks,
    log_region_tracks,
    log_scores,
    log_site,
    log_truth,
    open_recording,
    paths,
    save_run_blueprint,
    stage_recording,
)
from onebit.viz import inspect as rrd
from onebit.viz._series import update_indices
from onebit.viz.findinghumo import _cpda_label
from onebit.viz.tracks import region_positions

RUN_ID = "run-test-0001"


@pytest.fixture(autouse=True)
def strict_rerun():
    """Make Rerun raise on bad data instead of warning."""
    before = rr.strict_mode()
    rr.set_strict_mode(True)
    yield
    rr.set_strict_mode(before)


def crossings_frame() -> pl.DataFrame:
    return pl.DataFrame(
        {"t": [1.0, 2.5, 4.0, 6.0], "beam": ["a", "b", "a", "c"], "direction": [1, -1, -1, 1]},
        schema=tables.CROSSINGS,
    )


def aborted_frame() -> pl.DataFrame:
    return pl.DataFrame({"t": [3.0], "beam": ["a"], "side": [-1]}, schema=tables.ABORTED)


def truth_frame() -> pl.DataFrame:
    t = np.arange(0.0, 10.0, 0.5)
    return pl.DataFrame(
        {
            "t": np.r_[t, t],
            "target": ["A"] * len(t) + ["B"] * len(t),
            "x": np.r_[0.5 + 0.4 * t, 5.0 - 0.4 * t],
            "y": np.r_[np.full(len(t), 3.5), np.full(len(t), 0.5)],
        }
    )


def region_tracks_frame() -> pl.DataFrame:
    return tables.conform(
        pl.DataFrame(
            {
                "tracker": ["beams"] * 4,
                "track": ["u1", "u1", "u2", "u2"],
                "t": [0.0, 1.0, 0.0, 4.0],
                "region": ["r5", "r4", "r4", "r5"],
            }
        ),
        tables.TRACKS,
    ).sort("t")


def occupancy_frame() -> pl.DataFrame:
    return pl.DataFrame({"t": [0.0, 1.0, 4.0], "region": ["r4", "r4", "r4"], "count": [1, 2, 1]})


def scores_frame() -> pl.DataFrame:
    return pl.DataFrame({"tracker": ["beams"] * 3, "track": ["u1"] * 3, "t": [0.0, 1.0, 2.0], "error": [0.1, 0.5, 0.0]})


def write_full(out_dir, site, region_graph, *, stage="beams", recording_id=RUN_ID):
    with stage_recording(out_dir, stage, recording_id) as rec:
        log_site(rec, site, region_graph)
        log_crossings(rec, crossings_frame(), aborted=aborted_frame(), site=site)
        log_truth(rec, truth_frame())
        log_region_tracks(rec, "beams", region_tracks_frame(), region_graph)
        log_point_tracks(rec, "particles", pl.DataFrame({"track": ["p"], "t": [0.0], "x": [1.0], "y": [1.0]}))
        log_occupancy(rec, "beams", occupancy_frame())
        log_scores(rec, "beams", scores_frame())
    save_run_blueprint(out_dir / "rrd", units=site.units, looks=LOOKS)
    return out_dir / "rrd" / f"{stage}.rrd"


def test_stage_recording_holds_design_paths(tmp_path, lab):
    site, region_graph = lab
    path = write_full(tmp_path, site, region_graph)
    assert path.is_file()
    assert not list(path.parent.glob(".*partial")), "temp file left behind"
    rrd.verify(path)
    found = rrd.entity_paths(path)
    expected = {
        "site/boundary",
        "site/obstacles/0",
        "site/obstacles/1",
        "site/beams/a",
        "site/beams/d",
        "site/regions/r1",
        "site/regions/r5",
        "truth/A",
        "truth/A/trail",
        "truth/A/path",
        "truth/B",
        "sensors/a",
        "sensors/a/crossed",
        "sensors/b",
        "sensors/c",
        "beams/tracks/u1",
        "beams/tracks/u1/trail",
        "beams/tracks/u1/region",
        "beams/tracks/u1/regions",
        "beams/tracks/u2",
        "beams/occupancy/r4",
        "particles/tracks/p",
        "scores/beams/u1",
    }
    assert expected <= found, expected - found
    assert rrd.store_ids(path) == [("onebit", RUN_ID)]
    # the run's blueprint: a file and a recording of the run that holds only the layout
    assert (path.parent / "blueprint.rbl").is_file()
    assert rrd.store_ids(path.parent / "_blueprint.rrd") == [("onebit", RUN_ID)]
    assert rrd.entity_paths(path.parent / "_blueprint.rrd") == set()
    rrd.verify(path.parent / "_blueprint.rrd")


def test_cli_print_shows_paths_and_ids(tmp_path, lab):
    site, region_graph = lab
    path = write_full(tmp_path, site, region_graph)
    out = subprocess.run(
        [str(rrd.rerun_binary()), "rrd", "print", "--verbose", str(path)], capture_output=True, text=True, check=True
    ).stdout
    assert RUN_ID in out and '"onebit"' in out
    assert rrd._entity_paths_cli(path) == rrd.entity_paths(path)
    assert rrd._store_ids_cli(path) == rrd.store_ids(path) == [("onebit", RUN_ID)]


def test_stages_share_recording_id(tmp_path, lab):
    site, region_graph = lab
    with stage_recording(tmp_path, "site", RUN_ID) as rec:
        log_site(rec, site, region_graph)
    with stage_recording(tmp_path, "truth", RUN_ID) as rec:
        log_truth(rec, truth_frame())
    ids = [rrd.store_ids(tmp_path / "rrd" / f"{s}.rrd") for s in ("site", "truth")]
    assert ids[0] == ids[1] == [("onebit", RUN_ID)]
    assert "truth/A" in rrd.entity_paths(tmp_path / "rrd" / "truth.rrd")
    assert "truth/A" not in rrd.entity_paths(tmp_path / "rrd" / "site.rrd")


def test_failed_stage_leaves_no_file(tmp_path):
    with pytest.raises(RuntimeError, match="boom"):
        with stage_recording(tmp_path, "broken", RUN_ID) as rec:
            log_truth(rec, truth_frame())
            raise RuntimeError("boom")
    assert list((tmp_path / "rrd").iterdir()) == []


def test_empty_frames_log_nothing(tmp_path, lab):
    site, region_graph = lab
    with stage_recording(tmp_path, "empty", RUN_ID) as rec:
        log_crossings(rec, tables.empty(tables.CROSSINGS), aborted=tables.empty(tables.ABORTED))
        log_crossings(rec, None)
        log_truth(rec, tables.empty(tables.TRUTH))
        log_region_tracks(rec, "beams", tables.empty(tables.TRACKS), region_graph)
        log_point_tracks(rec, "beams", tables.empty(tables.TRACKS))
        log_occupancy(rec, "beams", pl.DataFrame(schema={"t": pl.Float64, "region": pl.String, "count": pl.Int64}))
        log_scores(rec, "beams", tables.empty(tables.SCORES))
    path = tmp_path / "rrd" / "empty.rrd"
    rrd.verify(path)
    assert rrd.entity_paths(path) == set()


def test_unknown_region_is_named(tmp_path, lab):
    _, region_graph = lab
    bad = region_tracks_frame().with_columns(region=pl.lit("nowhere"))
    with pytest.raises(ValueError, match="nowhere"):
        with stage_recording(tmp_path, "bad", RUN_ID) as rec:
            log_region_tracks(rec, "beams", bad, region_graph)


def test_missing_column_is_named(tmp_path):
    with pytest.raises(ValueError, match="direction"):
        with stage_recording(tmp_path, "bad", RUN_ID) as rec:
            log_crossings(rec, pl.DataFrame({"t": [0.0], "beam": ["a"]}))


def test_verify_rejects_garbage(tmp_path):
    bad = tmp_path / "bad.rrd"
    bad.write_bytes(b"not a recording")
    with pytest.raises(RuntimeError):
        rrd.verify(bad)
    with pytest.raises(FileNotFoundError):
        rrd.verify(tmp_path / "absent.rrd")


def test_open_recording_requires_id(tmp_path):
    with pytest.raises(ValueError, match="recording_id"):
        open_recording(tmp_path / "x.rrd", recording_id="")


def test_paths_escape_ids():
    assert paths.site_beam("a") == "site/beams/a"
    assert paths.track("beams", "u1") == "beams/tracks/u1"
    assert paths.occupancy("beams", "r1") == "beams/occupancy/r1"
    assert paths.score("beams", "u1") == "scores/beams/u1"
    assert paths.truth_path("A") == "truth/A/path"
    assert paths.trail(paths.truth("A")) == "truth/A/trail"
    assert paths.track_region("beams", "u1") == "beams/tracks/u1/region"
    assert paths.sensor_crossed("a") == "sensors/a/crossed"
    assert paths.istate("istate", "e", 3) == "istate/istate/e/3"
    assert paths.sensor("x/y") == "sensors/x\\/y"


def test_odd_ids_round_trip(tmp_path):
    odd = pl.DataFrame({"t": [0.0, 1.0], "beam": ["x/y", "a b^-1"], "direction": [1, -1]}, schema=tables.CROSSINGS)
    with stage_recording(tmp_path, "odd", RUN_ID) as rec:
        log_crossings(rec, odd)
    assert rrd.entity_paths(tmp_path / "rrd" / "odd.rrd") == {paths.sensor("x/y"), paths.sensor("a b^-1")}


def test_colors_are_stable():
    assert color_of("agent-1") == color_of("agent-1")
    c = colors_of(["r1", "r2", "r1"], alpha=100)
    assert c.shape == (3, 4) and c.dtype == np.uint8
    assert (c[0] == c[2]).all() and c[0, 3] == 100
    assert tuple(c[0]) == color_of("r1", alpha=100)


def test_update_indices_are_spread_and_end_at_the_last():
    at = update_indices(5000, 200)
    assert len(at) == 200 and at[0] == 0 and at[-1] == 4999 and (np.diff(at) > 0).all()
    assert update_indices(0, 10).size == 0


def test_region_positions_stay_inside(lab):
    _, region_graph = lab
    regions = np.array(region_graph.names)
    for slot in range(6):
        xy = region_positions(region_graph, regions, slot)
        assert (region_graph.region_of(xy[:, 0], xy[:, 1]) == regions).all()
    a, b = region_positions(region_graph, regions[:1], 0), region_positions(region_graph, regions[:1], 1)
    assert not np.allclose(a, b)


def test_cpda_label_is_short_chosen_first_then_the_most_probable_alternatives():
    label = _cpda_label("0 1 2", "1 0 2", True, 0.6, "0 1 2:0.200; 1 0 2:0.600; 2 1 0:0.150; 0 2 1:0.040; 1 2 0:0.010")
    lines = label.split("\n")
    assert lines[0] == "CPDA switch: tracks 1 2 3 -> 2 1 3 (p=0.60)"
    assert lines[1:] == ["  or 1 2 3: p=0.20", "  or 3 2 1: p=0.15", "  or 1 3 2: p=0.04", "  (+1 more, p <= 0.01)"]
    assert _cpda_label(
        "0 1 2", "0 1 2", False, 0.9, "0 1 2:0.9; 1 0 2:0.05; 2 1 0:0.04; 0 2 1:0.009; 1 2 0:0.001"
    ).endswith("(+1 more, p < 0.01)")
    assert _cpda_label("0 1", "0 1", False, 0.8, "0 1:0.800; 1 0:0.200").split("\n") == [
        "CPDA keep: tracks 1 2 -> 1 2 (p=0.80)",
        "  or 2 1: p=0.20",
    ]


def test_a_recording_does_not_import_pandas_and_pandas_still_works(tmp_path):
    """pyarrow imports pandas on its first numpy conversion (0.3-0.4 s); a recording stops
    that (arrow_without_pandas), and an explicit pandas use afterwards still gets pandas."""
    import sys

    code = f"""
import sys
import numpy as np
from onebit.viz.recording import stage_recording
with stage_recording({str(tmp_path)!r}, "s", "run-1") as rec:
    rec.log("p", __import__("rerun").Points2D(np.zeros((5, 2))))
assert "pandas" not in sys.modules, "pandas imported by a recording"
import pyarrow as pa
import pandas as pd
df = pa.table({{"x": [1, 2]}}).to_pandas()
assert isinstance(df, pd.DataFrame)
assert pa.array(pd.Categorical(["a", "b"])).type.id == pa.dictionary(pa.int8(), pa.string()).id
print("ok")
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-2000:]
    assert (tmp_path / "rrd" / "s.rrd").is_file()


def test_the_first_recording_imports_rerun_with_the_collector_paused_and_resumes_it(tmp_path):
    """open_recording imports Rerun with no collection during the import, and leaves the
    collector as it found it: on again when it was on, off when the caller had turned it off."""
    import sys

    code = f"""
import gc, sys
starts = []
def importing():  # rerun's module is being executed (importlib's mark while it runs)
    return getattr(getattr(sys.modules.get("rerun"), "__spec__", None), "_initializing", False)
gc.callbacks.append(lambda phase, info: starts.append(info) if phase == "start" and importing() else None)
from onebit.viz.recording import stage_recording
assert "rerun" not in sys.modules
with stage_recording({str(tmp_path)!r}, "s", "run-1") as rec:
    assert gc.isenabled()
assert "rerun.blueprint" in sys.modules and not importing() and not starts, starts
gc.disable()
from onebit.viz.recording import import_rerun
import_rerun()
assert not gc.isenabled()
print("ok")
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-2000:]
