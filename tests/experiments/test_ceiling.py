"""``onebit experiment ceiling``: the sequences a user may develop on, scored with the baselines."""

from __future__ import annotations

import polars as pl
import pytest

from onebit.cli import main
from onebit.core.errors import InputError
from onebit.core.site import load_site
from onebit.datasets.irtracking import import_irtracking
from onebit.datasets.irtracking_sim import write_irtracking
from onebit.experiments import ceiling
from onebit.readers.frames import read_frames_csv
from onebit.readers.tables_csv import read_truth_csv
from onebit.scoring.mot import metric_gate_rows


def test_held_out_sequences_are_never_read(tmp_path):
    for name in ceiling.HELD_OUT:
        assert name not in ceiling.SEQUENCES
        with pytest.raises(InputError, match="held out"):
            ceiling.sequence_files(tmp_path, name)


def test_quick_study_scores_trackers_and_baselines(tmp_path):
    data = tmp_path / "irtracking"
    for k, name in enumerate(ceiling.QUICK):
        write_irtracking(data / "data", name=name, frames=16, people=2, seed=k)
    out = tmp_path / "out"
    assert main(["experiment", "ceiling", str(out), "--data", str(data), "--quick", "--trackers", "istate"]) == 0
    res = pl.read_csv(out / "results.csv")
    assert set(res["sequence"]) == set(ceiling.QUICK)
    for name in ceiling.QUICK:
        rows = {r["tracker"]: r for r in res.filter(sequence=name).iter_rows(named=True)}
        assert {"istate", "room-centre", "stonesoup-gnn", "stonesoup-jpda"} <= set(rows)
        centre = rows["room-centre"]
        assert centre["status"] == "ok" and centre["max_tracks"] == 1 and centre["mota@1m"] <= centre["mota@1.5m"] <= 1
        assert rows["istate"]["status"] == "ok" and rows["istate"]["seconds"] > 0
        for r in rows.values():
            if r["status"] == "ok":
                assert r["idf1@1m"] <= r["idf1@1.5m"] + 1e-12  # a wider gate never loses a match
    assert not (out / "datasets" / "r1-medium").exists()


def test_unknown_tracker_and_missing_data(tmp_path):
    with pytest.raises(InputError, match="--data"):
        ceiling.run(tmp_path / "o")
    with pytest.raises(InputError, match="unknown positional tracker"):
        ceiling.run(tmp_path / "o", data=tmp_path, trackers=("beams",))


def test_stonesoup_baseline_follows_one_walker(tmp_path):
    """The Stone Soup peer (``.[bench]``): one walker under the array is one track near the truth."""
    pytest.importorskip("stonesoup")
    stonesoup_ceiling = pytest.importorskip("benchmarks.stonesoup_ceiling")
    f = write_irtracking(tmp_path / "data", frames=40, people=1, seed=2, radius_mm=900.0)
    import_irtracking(f.readings, tmp_path / "ds", truth=f.truth, radius=0.9, targets=1)
    site = load_site(tmp_path / "ds" / "site.toml")
    levels = read_frames_csv(tmp_path / "ds" / "frames.csv", [b.id for b in site.binary_sensors]).levels
    truth, _ = read_truth_csv(tmp_path / "ds" / "truth.csv")
    for jpda in (False, True):
        tracks = stonesoup_ceiling.track(levels, site, jpda=jpda)
        assert tracks["t"].is_between(0, 19.5).all()
        m = {r[1]: r[2] for r in metric_gate_rows("ss", tracks, truth, site, (1.5,))}
        assert m["mota@1.5m"] > 0.5 and m["max_tracks"] <= 2, (jpda, m)
