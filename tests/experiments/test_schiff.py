"""The quick version of ``onebit experiment schiff``: table, plots and the paper's orderings."""

from __future__ import annotations

import polars as pl

from onebit.experiments.schiff import RESULT_SCHEMA, run


def test_quick_study_writes_table_and_plots(tmp_path):
    out = run(tmp_path / "schiff", quick=True, echo=lambda s: None)
    res = pl.read_parquet(out / "results.parquet")
    assert res.schema == RESULT_SCHEMA
    assert set(res["estimator"]) == {"intruder", "naive"}
    assert pl.read_csv(out / "results.csv").height == res.height
    for png in ("fig3_naive_error_over_time.png", "fig4_naive.png", "fig5_beams22.png", "fig8_sensor_count.png"):
        assert (out / png).stat().st_size > 1000
    row = {(r["scenario"], r["refractory"], r["estimator"]): r for r in res.iter_rows(named=True)}
    beams0 = row[("beams22", 0.0, "intruder")]
    naive = row[("any", None, "naive")]
    # perfect beams, no refractory: within 2 cells nearly always, far better than the centre of the room
    assert beams0["within_2"] >= 0.95 and beams0["mean_error"] < naive["mean_error"] / 3
    # monotone fractions
    for r in res.iter_rows(named=True):
        assert r["within_1"] <= r["within_2"] <= r["within_3"] <= r["within_4"] <= 1.0
