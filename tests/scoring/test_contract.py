"""One contract over every tracker's scorer and the MOT hook (STYLE.md item 7), on empty input.

For each tracker of the pipeline's stage list: its outputs on empty input (the tracker run
on empty tables of the canonical schemas) are scored without truth and with truth; every
report row is ``(tracker, metric, float, unit)``, every ``<tracker>_scores`` table has the
SCORES schema and no rows, and nothing raises.
"""

from __future__ import annotations

import math

import polars as pl
import pytest

from onebit.core.tables import CROSSINGS, FRAMES, MOTION, PROXIMITY, SCORES
from onebit.pipeline.stages import TRACKERS
from onebit.scoring.crossings import ScoresConfig, score_crossings
from onebit.scoring.mot import mot_rows
from onebit.trackers.base import ARTIFACTS

ENTRIES = {e.name: e for e in TRACKERS}
#: the scenario each tracker is scored on, as its TrackerEntry declares it
SCENARIO = {e.name: e.scenario for e in TRACKERS}
#: empty tables of the canonical schemas, for every input a tracker may take
EMPTY_INPUTS = {
    "motion": MOTION,
    "frames": FRAMES,
    "proximity": PROXIMITY,
    "proximity_frames": FRAMES,
    "crossings": CROSSINGS,
    "corrected_crossings": CROSSINGS,
}


def test_every_tracker_is_covered(scenario_sites):
    for name, scenario in SCENARIO.items():  # each scored on a scenario the fixtures simulate
        assert scenario in scenario_sites, (name, scenario)


def _empty_outputs(name: str, site, region_graph) -> dict[str, pl.DataFrame]:
    spec = ENTRIES[name].spec
    inputs = {k: pl.DataFrame(schema=EMPTY_INPUTS[k]) for k in (*spec.needs, *spec.wants) if k in EMPTY_INPUTS}
    inputs["region_graph"] = region_graph
    out = spec.run(inputs, site, spec.config())
    return {f"{name}_{k}": v for k, v in out.items() if k != ARTIFACTS} | {
        k: v for k, v in inputs.items() if isinstance(v, pl.DataFrame)
    }


def _check(name: str, rows, made) -> None:
    for r in rows:
        assert len(r) == 4 and r[0] == name, r
        assert isinstance(r[1], str) and isinstance(r[2], float) and isinstance(r[3], str), r
    for key, df in made.items():
        assert isinstance(df, pl.DataFrame), key
        if key.endswith("_scores"):
            assert df.schema == SCORES, key
            assert df.height == 0, key


@pytest.mark.parametrize("with_truth", [False, True], ids=["no-truth", "truth"])
@pytest.mark.parametrize("name", sorted(SCENARIO))
def test_scorer_takes_empty_tracks(scenario_sites, name, with_truth):
    site, rg, truth = scenario_sites[SCENARIO[name]]
    tables = _empty_outputs(name, site, rg)
    assert tables[f"{name}_tracks"].height == 0
    if with_truth:
        tables["truth"] = truth
    c_rows, c_made = score_crossings(tables, ScoresConfig())
    tables.update(c_made)
    rows, made = ENTRIES[name].score(name, tables, site, rg)
    _check(name, rows, made)
    mot = mot_rows(name, ENTRIES[name].gate, tables | made, site, rg)
    _check(name, mot, {})
    if not with_truth:
        assert mot == []
    else:  # no tracks: every target at every truth frame is missed, nothing is matched
        m = {r[1]: r[2] for r in mot}
        assert m["false_positives@1m"] == 0 and m["id_switches@1m"] == 0 and math.isnan(m["motp@1m"])
        assert m["misses@1m"] == truth.drop_nulls("x").height and m["mota@1m"] <= 0
        if "mot_false_positives" in m:  # the paper's gate, where its unit is known without tracks
            assert m["mot_false_positives"] == 0 and m["id_switches"] == 0
            assert math.isnan(m["motp"])


@pytest.mark.parametrize("name", sorted(SCENARIO))
def test_mot_rows_without_any_truth_row_are_empty(scenario_sites, name):
    site, rg, truth = scenario_sites[SCENARIO[name]]
    tables = _empty_outputs(name, site, rg) | {"truth": truth.clear()}
    assert mot_rows(name, ENTRIES[name].gate, tables, site, rg) == []
