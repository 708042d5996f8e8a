"""End to end: onebit simulate pir14 -> onebit run -> report rows and Rerun entities."""

from __future__ import annotations

import polars as pl

from onebit.cli import main
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline
from onebit.viz.inspect import entity_paths


def test_simulate_run_report(tmp_path):
    data, out = tmp_path / "data", tmp_path / "run"
    assert main(["simulate", "pir14", str(data), "--seed", "4", "--duration", "60", "--param", "refractory=4"]) == 0
    res = run_pipeline(
        data,
        out,
        trackers=("intruder", "intruder-naive"),
        config={
            "intruder": {"particles": 500, "end": 60.0, "camera_position": [0.0, 0.0, 3.0]},
            "intruder-naive": {"end": 60.0},
        },
    )
    assert res.ok, res.status
    rep = res.report
    assert metric(rep, "rejects/rows") == 0.0 and metric(rep, "motion/suppressed") > 0
    assert metric(rep, "intruder/scored_iterations") == 30.0
    within = [metric(rep, f"intruder/within_{k}") for k in (1, 2, 3, 4)]
    assert 0.0 <= within[0] <= within[1] <= within[2] <= within[3] <= 1.0  # a CDF
    # each fraction recomputed from the per-iteration scores (errors in cells of 1 world unit)
    err = pl.read_parquet(out / "tables" / "intruder_scores.parquet")["error"]
    assert err.len() == 30
    assert within == [float((err <= k).mean()) for k in (1, 2, 3, 4)]
    assert metric(rep, "intruder/mean_error_cells") < metric(rep, "intruder-naive/mean_error_cells")
    tracks = pl.read_parquet(out / "tables" / "intruder_tracks.parquet")
    assert tracks.height == 30 and tracks["x"].null_count() == 0
    assert (out / "tables" / "intruder_coverage.parquet").exists()
    assert pl.read_parquet(out / "tables" / "intruder_camera.parquet").height == 30
    assert "particles = 500" in (out / "run.toml").read_text()
    ents = entity_paths(out / "rrd" / "intruder.rrd")
    assert {
        "intruder/particles",
        "intruder/estimate",
        "intruder/camera",
        "intruder/sensors/pir00",
        "site/sensors/pir00/coverage",
    } <= set(ents)
    assert "scores/intruder/intruder" in entity_paths(out / "rrd" / "scores.rrd")
    assert "sensors/pir00" in entity_paths(out / "rrd" / "motion.rrd")
