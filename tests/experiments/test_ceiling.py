"""``onebit experiment ceiling``: every sequence of the clone (or those chosen), scored with the peers."""

from __future__ import annotations

import sys

import polars as pl
import pytest

from onebit.cli import main
from onebit.core.errors import InputError
from onebit.core.site import load_site
from onebit.datasets.irtracking import import_irtracking
from onebit.datasets.irtracking_sim import write_irtracking
from onebit.experiments import ceiling
from onebit.experiments.peers import stonesoup
from onebit.readers.frames import read_frames_csv
from onebit.readers.tables_csv import read_truth_csv
from onebit.scoring.mot import metric_gate_rows


def clone(root, names, *, frames=16):
    """A small irtracking clone: ``root/data`` with one simulated sequence per name."""
    for k, name in enumerate(names):
        write_irtracking(root / "data", name=name, frames=frames, people=2, seed=k)
    return root


def test_every_sequence_with_truth_and_readings_is_found(tmp_path):
    data = clone(tmp_path / "irtracking", ["walk-b", "walk-a"])
    (data / "data" / "walk-a.txt").unlink()  # the CVML detections alone still make a sequence
    (data / "data" / "lonely_gt.xml").write_text("<dataset/>")  # truth without readings: not one
    (data / "data" / "notes.xml").write_text("<dataset/>")  # readings without truth: not one
    assert ceiling.find_sequences(data) == ("walk-a", "walk-b")
    assert ceiling.find_sequences(data / "data") == ("walk-a", "walk-b")  # the data folder itself
    assert ceiling.sequence_files(data, "walk-a")[0].name == "walk-a.xml"
    assert ceiling.choose_sequences(data) == ("walk-a", "walk-b")
    assert ceiling.choose_sequences(data, ("walk-b",)) == ("walk-b",)
    assert ceiling.choose_sequences(data, ("walk-b", "walk-a", "walk-b")) == ("walk-b", "walk-a")


def test_an_unknown_sequence_is_named_with_those_found(tmp_path):
    data = clone(tmp_path / "irtracking", ["walk-a", "walk-b"])
    with pytest.raises(InputError, match=r"unknown sequence 'lonely'.*found: walk-a, walk-b") as err:
        ceiling.choose_sequences(data, ("walk-a", "lonely"))
    assert err.value.field == "sequences"
    with pytest.raises(InputError, match="found: walk-a, walk-b"):
        ceiling.choose_sequences(data, ())
    with pytest.raises(InputError, match="unknown sequence 'testanton'"):  # --quick needs its two sequences
        ceiling.choose_sequences(data, quick=True)
    out = tmp_path / "out"
    assert main(["experiment", "ceiling", str(out), "--data", str(data), "--sequences", "walk-a,lonely"]) == 2
    assert not out.exists()  # refused before anything is imported or written


def test_a_folder_without_sequences_is_refused(tmp_path):
    with pytest.raises(InputError, match="not a folder"):
        ceiling.find_sequences(tmp_path / "absent")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no irtracking sequence"):
        ceiling.choose_sequences(tmp_path / "empty")


def test_default_runs_every_sequence_found_and_scores_the_peers(tmp_path, monkeypatch):
    """Without Stone Soup (hidden here) its rows name the bench extra and the rest is scored; the
    repository's ``benchmarks`` (hidden too) is not needed."""
    for absent in ("stonesoup", "benchmarks"):
        monkeypatch.setitem(sys.modules, absent, None)  # `import stonesoup` now fails, installed or not
    data = clone(tmp_path / "irtracking", ["walk-a", "walk-b"])
    out = tmp_path / "out"
    assert main(["experiment", "ceiling", str(out), "--data", str(data), "--trackers", "istate"]) == 0
    res = pl.read_csv(out / "results.csv")
    assert set(res["sequence"]) == {"walk-a", "walk-b"}
    for name in ("walk-a", "walk-b"):
        rows = {r["tracker"]: r for r in res.filter(sequence=name).iter_rows(named=True)}
        assert set(rows) == {"istate", "room-centre", "stonesoup-gnn", "stonesoup-jpda"}
        centre = rows["room-centre"]
        assert centre["status"] == "ok" and centre["max_tracks"] == 1 and centre["mota@1m"] <= centre["mota@1.5m"] <= 1
        assert 0 <= centre["hota@1m"] <= centre["hota@1.5m"] + 1e-12 <= 1 + 1e-12
        assert rows["istate"]["status"] == "ok" and rows["istate"]["seconds"] > 0
        assert rows["istate"]["hota@1.5m"] is not None
        for label in ("stonesoup-gnn", "stonesoup-jpda"):
            assert "bench extra" in rows[label]["status"] and "onebit[bench]" in rows[label]["status"]
            assert rows[label]["mota@1.5m"] is None
        for r in rows.values():
            if r["status"] == "ok":
                assert r["idf1@1m"] <= r["idf1@1.5m"] + 1e-12  # a wider gate never loses a match


def test_sequences_selects_some(tmp_path):
    data = clone(tmp_path / "irtracking", ["walk-a", "walk-b", "walk-c"])
    out = tmp_path / "out"
    argv = ["experiment", "ceiling", str(out), "--data", str(data), "--trackers", "istate", "--sequences", "walk-c"]
    assert main(argv) == 0
    res = pl.read_csv(out / "results.csv")
    assert set(res["sequence"]) == {"walk-c"}
    assert sorted(p.name for p in (out / "datasets").iterdir()) == ["walk-c"]


def test_quick_runs_the_two_short_sequences(tmp_path):
    data = clone(tmp_path / "irtracking", [*ceiling.QUICK, "walk-a"])
    out = tmp_path / "out"
    assert main(["experiment", "ceiling", str(out), "--data", str(data), "--quick", "--trackers", "istate"]) == 0
    assert set(pl.read_csv(out / "results.csv")["sequence"]) == set(ceiling.QUICK)


def test_unknown_tracker_and_missing_data(tmp_path):
    with pytest.raises(InputError, match="--data"):
        ceiling.run(tmp_path / "o")
    with pytest.raises(InputError, match="unknown positional tracker"):
        ceiling.run(tmp_path / "o", data=tmp_path, trackers=("beams",))


def test_the_benchmarks_command_runs_the_packages_peer():
    """``python -m benchmarks.stonesoup_ceiling`` (a clone only) is the package's peer."""
    bench = pytest.importorskip("benchmarks.stonesoup_ceiling")  # present in a clone only
    assert bench.track is stonesoup.track and bench.main is stonesoup.main


def test_stonesoup_baseline_follows_one_walker(tmp_path):
    """The Stone Soup peer (``onebit[bench]``): one walker under the array is one track near the truth."""
    pytest.importorskip("stonesoup")
    assert stonesoup.missing() is None
    f = write_irtracking(tmp_path / "data", frames=40, people=1, seed=2, radius_mm=900.0)
    import_irtracking(f.readings, tmp_path / "ds", truth=f.truth, radius=0.9, targets=1)
    site = load_site(tmp_path / "ds" / "site.toml")
    levels = read_frames_csv(tmp_path / "ds" / "frames.csv", [b.id for b in site.binary_sensors]).levels
    truth, _ = read_truth_csv(tmp_path / "ds" / "truth.csv")
    for jpda in (False, True):
        tracks = stonesoup.track(levels, site, jpda=jpda)
        assert tracks["t"].is_between(0, 19.5).all()
        m = {r[1]: r[2] for r in metric_gate_rows("ss", tracks, truth, site, (1.5,))}
        assert m["mota@1.5m"] > 0.5 and m["max_tracks"] <= 2, (jpda, m)
