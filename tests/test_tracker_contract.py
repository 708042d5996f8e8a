"""One contract over every registered tracker (STYLE.md item 7).

For each tracker, on a small simulated dataset of its kind: the pipeline runs it; its
``tracks`` output has the canonical TRACKS schema and names the tracker; the stage is a pure
function (same inputs and seed -> identical outputs); and empty inputs (every table with
its schema but no rows) give empty tables of the right schema or a clear OnebitError -- never
another exception.
"""

from __future__ import annotations

from pathlib import Path

import polars as pl
import pytest

from onebit.datasets.region_graph import build_region_graph
from onebit.datasets.scenarios import get_scenario
from onebit.datasets.site import load_site
from onebit.errors import OnebitError
from onebit.pipeline.runner import run_pipeline
from onebit.tables import TRACKS
from onebit.trackers import load_trackers
from onebit.viz import StageLog

#: the dataset each tracker is checked on: scenario, duration, params
DATASETS = {
    "beams-lab": ("beams-lab", 40.0, {}),
    "pir14": ("pir14", 40.0, {}),
    "proximity-line": ("proximity-line", None, {}),
    "hallway": ("hallway", 40.0, {}),
    "istate-room": ("istate-room", 20.0, {}),
}
TRACKER_DATA = {
    "beams": "beams-lab",
    "intruder": "pir14",
    "intruder-naive": "pir14",
    "clustertrack": "proximity-line",
    "findinghumo": "hallway",
    "hmm1": "hallway",
    "hmm2": "hallway",
    "istate": "istate-room",
}

REGISTRY = load_trackers()


def test_every_registered_tracker_is_covered():
    assert set(REGISTRY) == set(TRACKER_DATA)


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


@pytest.mark.parametrize("name", sorted(TRACKER_DATA))
def test_same_inputs_same_outputs(runs, name):
    spec = REGISTRY[name]
    run = runs[TRACKER_DATA[name]]
    site = load_site(run.parent / TRACKER_DATA[name] / "site.toml")
    inputs = _inputs(run, spec, site)
    a = spec.run(dict(inputs), site, spec.config(), StageLog(None))
    b = spec.run(dict(inputs), site, spec.config(), StageLog(None))
    assert a.keys() == b.keys()
    for k in a:
        if isinstance(a[k], pl.DataFrame):
            # wall-clock measurements (the decoder's seconds per slot) are the only thing allowed to differ
            wall = [c for c in a[k].columns if c == "seconds" or c.endswith("_seconds")]
            assert a[k].drop(wall).equals(b[k].drop(wall)), (name, k)


@pytest.mark.parametrize("name", sorted(TRACKER_DATA))
def test_empty_inputs_are_handled(runs, name):
    spec = REGISTRY[name]
    run = runs[TRACKER_DATA[name]]
    site = load_site(run.parent / TRACKER_DATA[name] / "site.toml")
    inputs = {k: (v.clear() if isinstance(v, pl.DataFrame) else v) for k, v in _inputs(run, spec, site).items()}
    try:
        out = spec.run(inputs, site, spec.config(), StageLog(None))
    except OnebitError as exc:  # a clear refusal is fine
        assert str(exc)
        return
    assert out["tracks"].schema == TRACKS
