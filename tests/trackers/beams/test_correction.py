"""The ``correct`` pipeline stage: config, tables, the beams tracker on the corrected string,
the recovered-crossing score, Rerun entities, and the 20-seed end-to-end study."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from onebit.core.errors import ConfigError, InputError
from onebit.core.region_graph import build_region_graph
from onebit.core.site import load_site
from onebit.datasets.beams_sim import write_beams_dataset
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline
from onebit.readers.rows import read_csv_rows
from onebit.readers.tables_csv import true_crossings_columns, true_crossings_from_rows
from onebit.scoring.correction import recovered_matches
from onebit.trackers.beams.correction import CORRECTED_CROSSINGS, CorrectConfig, corrected_frame
from onebit.trackers.beams.counting import RegionEdges, correct, verify
from onebit.viz.inspect import entity_paths


@pytest.fixture(scope="module")
def building_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("correct")
    data = write_beams_dataset(root / "data", "beams-building", seed=2, duration=300.0, drop=0.1, camera=False)
    res = run_pipeline(data, root / "run", trackers=("beams",), config={"correct": {"n": 3}})
    return data, res


def test_config_validation_names_the_field():
    with pytest.raises(ConfigError, match=r"CorrectConfig\.n"):
        CorrectConfig(n=0)
    with pytest.raises(ConfigError, match=r"CorrectConfig\.placement"):
        CorrectConfig(placement="middle")
    with pytest.raises(ConfigError, match=r"CorrectConfig\.initial\.r1"):
        CorrectConfig(initial={"r1": -1})
    with pytest.raises(ConfigError, match=r"CorrectConfig\.enabled"):
        CorrectConfig(enabled="no")
    assert CorrectConfig().placement == "midpoint"


def test_stage_tables_and_report(building_run):
    _, res = building_run
    assert res.ok, res.status
    assert res.status["correct"].startswith("ok")
    out = res.out / "tables"
    cor = pl.read_parquet(out / "corrected_crossings.parquet")
    obs = pl.read_parquet(out / "crossings.parquet")
    ins = pl.read_parquet(out / "correct_insertions.parquet")
    init = pl.read_parquet(out / "correct_initial.parquet")
    assert cor.schema == CORRECTED_CROSSINGS
    assert cor["t"].is_sorted()
    # the observed string is kept, in order, and the insertions are the rest
    assert cor.filter(~pl.col("inserted")).select("t", "beam", "direction").equals(obs.select("t", "beam", "direction"))
    n_ins = metric(res.report, "correct/inserted")
    assert n_ins == ins.height == cor["inserted"].sum() > 0
    assert metric(res.report, "correct/accepted") == 0.0  # 10 % dropped: the raw string is not in L(M_C)
    assert init["count"].sum() == 3 == metric(res.report, "correct/n")
    # the corrected string is in L(M_C) from the reported eta_0

    rg = build_region_graph(load_site(res.out.parent / "data" / "site.toml"))
    src, tgt = rg.endpoint_arrays(cor["beam"], cor["direction"].to_numpy())
    eta0 = init.sort(pl.col("region").replace_strict({r: i for i, r in enumerate(rg.names)}))["count"].to_numpy()
    assert verify(src, tgt, eta0).accepted
    # ... so Algorithm 1 on it needs no more than n agents, and beams read the corrected string
    assign = pl.read_parquet(out / "beams_assignment.parquet")
    assert assign.height == cor.height
    assert metric(res.report, "beams/agents") <= 3
    rec = pl.read_parquet(out / "correct_recovered.parquet")
    assert rec.height == metric(res.report, "correct/dropped") > 0
    restored = rec["inserted_row"].drop_nulls()
    assert metric(res.report, "correct/restored") == restored.len() > 0
    assert metric(res.report, "correct/recovered") == pytest.approx(restored.len() / rec.height)
    # every restoring insertion is an inserted row with the dropped crossing's beam and direction
    hit = rec.drop_nulls("inserted_row").join(
        cor.with_row_index("inserted_row").with_columns(pl.col("inserted_row").cast(pl.Int64)),
        on="inserted_row",
        suffix="_ins",
    )
    assert hit.height == restored.len() and hit["inserted"].all()
    assert (hit["beam"] == hit["beam_ins"]).all() and (hit["direction"] == hit["direction_ins"]).all()


def test_inserted_crossings_are_their_own_rerun_entity(building_run):
    _, res = building_run
    paths = entity_paths(res.out / "rrd" / "correct.rrd")
    assert {"correct/crossings/inserted", "correct/crossings/observed", "correct/log"} <= paths


def test_dataset_run_toml_gives_the_known_initial_condition(tmp_path):
    """The simulator writes [correct] n and initial (eta_0) into the dataset's run.toml; the
    stage uses it unless --config has a [correct] section, and enabled = false skips it."""
    data = write_beams_dataset(tmp_path / "d", "beams-building", seed=4, duration=60.0, drop=0.1, camera=False)
    truth = pl.read_csv(data / "truth.csv").sort("t").group_by("target", maintain_order=True).first()
    assert "n = 3" in (data / "run.toml").read_text() and truth.height == 3
    res = run_pipeline(data, tmp_path / "r", trackers=("beams",), rrd=False)
    assert res.status["correct"].startswith("ok"), res.status["correct"]
    init = pl.read_parquet(res.out / "tables" / "correct_initial.parquet")

    rg = build_region_graph(load_site(data / "site.toml"))
    start = rg.region_of(truth["x"].to_numpy(), truth["y"].to_numpy()).tolist()
    # eta_0 is the truth's first positions, counted per region
    assert dict(init.iter_rows()) == {r: start.count(r) for r in rg.names}
    assert init["count"].sum() == 3
    assert "[correct]" in (res.out / "run.toml").read_text()
    off = run_pipeline(data, tmp_path / "off", trackers=("beams",), config={"correct": {"enabled": False}}, rrd=False)
    assert off.status["correct"].startswith("skipped") and "enabled = false" in off.status["correct"]


def test_stage_skipped_without_agent_count(tmp_path):
    data = write_beams_dataset(tmp_path / "d", "beams-lab", seed=0, duration=30.0, camera=False)
    (data / "run.toml").unlink()  # no known n: neither site.toml targets nor a [correct] section
    site = (data / "site.toml").read_text()  # the simulator declares its agents as targets: drop them
    (data / "site.toml").write_text("\n".join(ln for ln in site.splitlines() if not ln.startswith("targets")) + "\n")
    res = run_pipeline(data, tmp_path / "r", trackers=("beams",), rrd=False)
    assert res.status["correct"].startswith("skipped") and "[correct] n" in res.status["correct"]
    res2 = run_pipeline(
        data, tmp_path / "r2", trackers=("beams",), config={"correct": {"n": 2, "start_region": "nowhere"}}
    )
    assert res2.status["correct"].startswith("failed") and "start_region" in res2.status["correct"]
    res3 = run_pipeline(
        data, tmp_path / "r3", trackers=("beams",), config={"correct": {"n": 2, "start_region": "r1"}}, rrd=False
    )
    assert res3.status["correct"].startswith("ok")


def test_truth_crossings_reader_keeps_dropped_flag(tmp_path):
    p = tmp_path / "truth_crossings.csv"
    p.write_text("t,beam,direction,target,dropped\n0.5,a,1,agent1,0\n1.5,b,-1,agent2,1\n2.5,a,1,agent1,2\n")
    cols = true_crossings_columns(p)
    assert cols[-1] == "dropped"
    df, rej = true_crossings_from_rows(read_csv_rows(p, cols), ("a", "b"), path=p)
    assert df["dropped"].to_list() == [False, True]
    assert rej["line"].to_list() == [4] and "dropped" in rej["reason"][0]


def test_recovered_needs_beam_direction_and_the_agents_neighbouring_crossings():
    sim = pl.DataFrame(
        {
            "t": [1.0, 2.0, 3.0, 4.0, 5.0],
            "beam": ["a", "b", "c", "d", "e"],
            "direction": pl.Series([1, 1, 1, -1, 1], dtype=pl.Int8),
            "target": ["x", "x", "x", "y", "y"],
            "dropped": [False, True, False, True, False],
        }
    )
    corrected = pl.DataFrame(
        {
            "t": [1.0, 2.5, 3.0, 3.5, 4.2, 5.0],
            "beam": ["a", "b", "c", "d", "d", "e"],
            "direction": pl.Series([1, 1, 1, 1, -1, 1], dtype=pl.Int8),
            "inserted": [False, True, False, True, True, False],
        }
    )
    rec = recovered_matches(corrected, sim).sort("t")
    # b of x restored at 2.5 (between x's 1.0 and 3.0); d^-1 of y restored by the 4.2 one
    # (the d at 3.5 has the wrong direction)
    assert rec["inserted_row"].to_list() == [1, 4]
    late = corrected.with_columns(t=pl.Series([1.0, 3.2, 3.0, 3.5, 5.5, 5.6]))
    assert recovered_matches(late, sim)["inserted_row"].null_count() == 2  # outside the windows


# --------------------------------------------------------------------------- 20 seeds, end to end

SEEDS = range(20)


def _baseline_restored(data, run_out) -> int:
    """The first version's setting on the same observed string: eta_0 unknown (n = 3), every
    insertion at the earliest place of its window (times interpolated)."""

    t = run_out / "tables"
    obs = pl.read_parquet(t / "crossings.parquet")
    rg = build_region_graph(load_site(data / "site.toml"))
    edges = RegionEdges.from_region_graph(rg)
    src, tgt = rg.endpoint_arrays(obs["beam"], obs["direction"].to_numpy())
    res = correct(src, tgt, edges, n_agents=3, placement="earliest")
    rec = recovered_matches(corrected_frame(obs, res, edges), pl.read_parquet(t / "sim_crossings.parquet"))
    return rec["inserted_row"].drop_nulls().len()


@pytest.fixture(scope="module")
def twenty_seeds(tmp_path_factory):
    """beams-building, drop 0.05, no camera, 300 s: the dataset's own [correct] (known eta_0,
    placement "midpoint"), and the same run with the correction disabled."""
    root = tmp_path_factory.mktemp("seeds")
    rows = []
    for seed in SEEDS:
        data = write_beams_dataset(
            root / f"d{seed}", "beams-building", seed=seed, duration=300.0, drop=0.05, camera=False
        )
        on = run_pipeline(data, root / f"on{seed}", trackers=("beams",), rrd=False)
        off = run_pipeline(
            data, root / f"off{seed}", trackers=("beams",), config={"correct": {"enabled": False}}, rrd=False
        )
        assert on.ok and off.ok, (on.status, off.status)
        assert on.status["correct"].startswith("ok") and off.status["correct"].startswith("skipped")
        dropped = metric(on.report, "correct/dropped")
        rows.append(
            dict(
                seed=seed,
                dropped=dropped,
                inserted=metric(on.report, "correct/inserted"),
                restored=metric(on.report, "correct/restored"),
                recovered=metric(on.report, "correct/recovered"),
                baseline=_baseline_restored(data, on.out) / dropped if dropped else 1.0,
                acc_on=metric(on.report, "beams/assignment_accuracy"),
                acc_off=metric(off.report, "beams/assignment_accuracy"),
            )
        )
    return pl.DataFrame(rows)


def test_assignment_accuracy_after_correction_at_least_without(twenty_seeds):
    df = twenty_seeds
    assert df["acc_on"].mean() >= df["acc_off"].mean(), df


def test_known_eta0_and_midpoint_restore_more_than_the_first_version(twenty_seeds):
    """Known eta_0 (the paper's setting) and the time-midpoint placement against the first
    version (unknown eta_0, earliest place) on the same observed strings: more dropped
    crossings restored on average (measured 0.70 against 0.47)."""
    df = twenty_seeds.filter(pl.col("dropped") > 0)
    assert df["recovered"].mean() > df["baseline"].mean(), df


@pytest.mark.xfail(
    strict=True,
    reason="measured 0.70 with known eta_0 and midpoint placement (0.47 before; see docs/beams-correct.md): "
    "min-insertion correction cannot restore drops that never violate the counts (the minimum needs 59 "
    "insertions for 71 drops), nor tell parallel beams apart",
)
def test_dropped_crossings_recovered_on_average(twenty_seeds):
    """The issue's bar: correct/recovered averaged over 20 seeds >= 0.9 (see docs/beams-correct.md
    for the measured value and why minimum-insertion correction cannot restore every drop)."""
    df = twenty_seeds.filter(pl.col("dropped") > 0)
    assert df.height > 10
    assert float(np.mean(df["recovered"].to_numpy())) >= 0.9, df


def test_broken_dataset_run_toml_is_refused_naming_the_file(tmp_path):
    """A dataset whose run.toml is not TOML is refused when the run starts, naming the file;
    nothing is written (every input is checked before any work)."""
    data = write_beams_dataset(tmp_path / "d", "beams-building", seed=0, duration=30.0, drop=0.0, camera=False)
    (data / "run.toml").write_text("[correct\nn = 3\n")
    with pytest.raises(InputError, match=r"run\.toml: not valid TOML"):
        run_pipeline(data, tmp_path / "run", trackers=("beams",), rrd=False)
    assert not (tmp_path / "run" / "run.toml").exists()
