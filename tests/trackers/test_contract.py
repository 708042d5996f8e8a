"""One contract over every tracker of the pipeline's stage list (STYLE.md item 7).

For each tracker, on a small simulated dataset of its kind: the pipeline runs it; its
``tracks`` output has the canonical TRACKS schema and names the tracker; the stage is a pure
function (same inputs and seed -> identical outputs, nothing excepted); and empty inputs
(every table with its schema but no rows) give the same tables, with the same schemas, and
no rows of tracks -- never an error. Its scorer and its Rerun logging take the empty output
too.
"""

from __future__ import annotations

from pathlib import Path

import polars as pl
import pytest
import rerun as rr

from onebit.core.region_graph import build_region_graph
from onebit.core.site import load_site
from onebit.core.tables import TRACKS
from onebit.datasets.catalogue import get_scenario
from onebit.pipeline.runner import run_pipeline
from onebit.pipeline.stages import TRACKERS
from onebit.trackers.base import ARTIFACTS, PROGRESS

#: the dataset each tracker is checked on: scenario, duration, params
DATASETS = {
    "beams-lab": ("beams-lab", 40.0, {}),
    "pir14": ("pir14", 40.0, {}),
    "proximity-line": ("proximity-line", None, {}),
    "proximity-grid": ("proximity-grid", None, {}),
    "hallway": ("hallway", 40.0, {}),
    "istate-room": ("istate-room", 20.0, {}),
}
#: the scenario of each tracker, as its TrackerEntry declares it
TRACKER_DATA = {e.name: e.scenario for e in TRACKERS}

ENTRIES = {e.name: e for e in TRACKERS}


def test_every_tracker_of_the_stage_list_is_covered():
    for entry in TRACKERS:  # scored, logged, MOT-gated and tested on a scenario, each declared once in the stage list
        assert entry.score is not None and entry.viz is not None and entry.gate is not None, entry.name
        assert entry.scenario in DATASETS, (entry.name, entry.scenario)


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("contract")
    out = {}
    for key, (scenario, duration, params) in DATASETS.items():
        data = get_scenario(scenario).write(
            root / key, seed=3, duration=duration, agents=None, drop=0.0, camera=False, params=params
        )
        trackers = tuple(t for t, d in TRACKER_DATA.items() if d == key)
        res = run_pipeline(data, root / f"{key}-run", trackers=trackers)
        for t in trackers:
            assert res.status[t].startswith("ok"), (t, res.status[t])
        out[key] = root / f"{key}-run"
    return out


def _inputs(run: Path, spec, site) -> dict:
    tables = run / "tables"
    inputs = {}
    for k in (*spec.needs, *spec.wants):
        p = tables / f"{k}.parquet"
        if p.exists():
            inputs[k] = pl.read_parquet(p)
    inputs["region_graph"] = build_region_graph(site)
    return inputs


@pytest.mark.parametrize("name", sorted(TRACKER_DATA))
def test_tracks_have_the_canonical_schema(runs, name):
    tracks = pl.read_parquet(runs[TRACKER_DATA[name]] / "tables" / f"{name}_tracks.parquet")
    assert tracks.schema == TRACKS
    assert tracks.height > 0
    assert tracks["tracker"].unique().to_list() == [name]
    assert tracks["t"].is_not_null().all()


def _tables(out: dict) -> dict[str, pl.DataFrame]:
    return {k: v for k, v in out.items() if k != ARTIFACTS}


@pytest.mark.parametrize("name", sorted(TRACKER_DATA))
def test_same_inputs_same_outputs(runs, name):
    spec = ENTRIES[name].spec
    run = runs[TRACKER_DATA[name]]
    site = load_site(run.parent / TRACKER_DATA[name] / "site.toml")
    inputs = _inputs(run, spec, site)
    a = _tables(spec.run(dict(inputs), site, spec.config()))
    b = _tables(spec.run(dict(inputs), site, spec.config()))
    assert a.keys() == b.keys()
    for k in a:
        assert isinstance(a[k], pl.DataFrame), (name, k)
        assert a[k].equals(b[k]), (name, k)


@pytest.mark.parametrize("name", sorted(TRACKER_DATA))
def test_empty_inputs_give_empty_outputs_of_the_same_schema(runs, name, tmp_path):
    entry = ENTRIES[name]
    spec = entry.spec
    run = runs[TRACKER_DATA[name]]
    site = load_site(run.parent / TRACKER_DATA[name] / "site.toml")
    inputs = _inputs(run, spec, site)
    full = _tables(spec.run(dict(inputs), site, spec.config()))
    empty_in = {k: (v.clear() if isinstance(v, pl.DataFrame) else v) for k, v in inputs.items()}
    out = spec.run(empty_in, site, spec.config())
    empty = _tables(out)
    assert empty["tracks"].schema == TRACKS
    assert empty["tracks"].height == 0
    assert empty.keys() <= full.keys(), (name, empty.keys() - full.keys())
    for k, df in empty.items():
        assert df.schema == full[k].schema, (name, k)
    # the scorer and the Rerun logging take the empty output
    tables = {f"{name}_{k}": v for k, v in empty.items()}
    rows, made = entry.score(name, tables, site, inputs["region_graph"])
    assert all(isinstance(r[2], float) for r in rows)
    rec = rr.RecordingStream("onebit-test")
    rec.save(str(tmp_path / "empty.rrd"))
    entry.viz(rec, name, out, site=site, region_graph=inputs["region_graph"], config=spec.config(), tables=tables)
    rec.flush()


#: trackers with a long loop that must report progress (filter iterations, HMM windows)
REPORTS_PROGRESS = {"intruder", "findinghumo", "hmm1", "hmm2", "findinghumo-flow"}


@pytest.mark.parametrize("name", sorted(TRACKER_DATA))
def test_a_progress_callback_changes_nothing_and_counts_up(runs, name):
    spec = ENTRIES[name].spec
    run = runs[TRACKER_DATA[name]]
    site = load_site(run.parent / TRACKER_DATA[name] / "site.toml")
    inputs = _inputs(run, spec, site)
    calls: list[tuple[int, int]] = []
    plain = _tables(spec.run(dict(inputs), site, spec.config()))
    told = _tables(spec.run({**inputs, PROGRESS: lambda done, total: calls.append((done, total))}, site, spec.config()))
    assert plain.keys() == told.keys() and all(plain[k].equals(told[k]) for k in plain), name
    assert all(0 <= d <= t for d, t in calls) and [d for d, _ in calls] == sorted(d for d, _ in calls)
    if name in REPORTS_PROGRESS:
        assert len(calls) > 1 and calls[-1][0] == calls[-1][1], (name, calls[-3:])
