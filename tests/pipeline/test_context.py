"""What a stage may do to the run it shares (:mod:`onebit.pipeline.context`): return only the
tables it declares, read the config without writing to it, find the time origin on the context."""

from __future__ import annotations

import shutil
import tomllib
from pathlib import Path

import polars as pl
import pytest

from onebit.core.region_graph import build_region_graph
from onebit.core.site import load_site
from onebit.datasets.builtin import builtin_site_path
from onebit.pipeline import runner
from onebit.pipeline import stages as declaration
from onebit.pipeline.context import RunContext, Stage, StageContractError, check_made
from onebit.pipeline.reading import run_time_origin
from onebit.pipeline.runner import run_pipeline
from onebit.pipeline.stages import stages
from onebit.readers import logs
from onebit.readers.timebase import TimeOrigin

FRAME = pl.DataFrame({"t": [0.0]})


def _stage(*makes: str) -> Stage:
    return Stage("probe", (), makes, lambda ctx: None, lambda ctx: {})


@pytest.fixture
def hallway(tmp_path):
    d = tmp_path / "data"
    d.mkdir()
    shutil.copy(builtin_site_path("hallway"), d / "site.toml")
    (d / "motion.csv").write_text("t,sensor,value\n0,104,1\n1.6,104,0\n2.1,103,1\n3.7,103,0\n4.2,102,1\n5.8,102,0\n")
    return d


def test_a_stage_returns_only_what_it_declares():
    check_made(_stage("a", "b"), {"a": FRAME}, {})  # fewer than declared is fine
    check_made(_stage("x_*"), {"x_tracks": FRAME, "x_extra": FRAME}, {})
    with pytest.raises(StageContractError, match=r"stage 'probe' returned table\(s\) \['c'\] it does not declare"):
        check_made(_stage("a", "b"), {"a": FRAME, "c": FRAME}, {})
    with pytest.raises(StageContractError, match="does not declare"):  # a prefix is not a name
        check_made(_stage("x_*"), {"x": FRAME}, {})
    with pytest.raises(StageContractError, match=r"non-table value\(s\) \['a \(list\)'\]"):
        check_made(_stage("a"), {"a": [1, 2]}, {})
    with pytest.raises(StageContractError, match=r"\['a'\] that an earlier stage made"):
        check_made(_stage("a"), {"a": FRAME}, {"a": FRAME})
    check_made(_stage("a"), {"a": FRAME, "artifacts": {"model": 1}}, {}, extra=("artifacts",))


def test_every_declared_stage_keeps_its_declaration(hallway, tmp_path):
    """A whole run through the runner's check: every stage that ran is ok, so every table it
    returned was declared and new."""
    res = run_pipeline(hallway, tmp_path / "run", trackers=["hmm1", "findinghumo"], rrd=False)
    assert res.ok, res.status
    made = {p.stem for p in (tmp_path / "run" / "tables").glob("*.parquet")} - {"rejects"}
    ran = [st for st in stages() if res.status.get(st.name, "").startswith("ok")]
    assert all(any(st.declares(t) for st in ran) for t in made), made


def test_a_stage_returning_an_undeclared_table_fails_clearly(hallway, tmp_path, monkeypatch):
    def sneaky(ctx):
        return {"motion_copy": ctx.tables["motion"]}

    extra = Stage("sneaky", ("motion",), ("levels",), lambda ctx: None, sneaky)
    monkeypatch.setattr(declaration, "stages", lambda entries: [*stages(entries), extra])
    res = run_pipeline(hallway, tmp_path / "run", trackers=["hmm1"], rrd=False)
    assert not res.ok
    assert "returned table(s) ['motion_copy'] it does not declare (makes = ['levels'])" in res.status["sneaky"]
    assert res.status["hmm1"].startswith("ok")  # the other stages keep their outputs
    assert not (tmp_path / "run" / "tables" / "motion_copy.parquet").exists()
    assert (tmp_path / "run" / "logs" / "sneaky.traceback.txt").exists()


def test_a_stage_resolves_its_config_beside_the_given_one(hallway, tmp_path):
    site = load_site(hallway / "site.toml")
    given = {"motion": {"chatter_window": 0.5}}
    ctx = RunContext(hallway, tmp_path, site, build_region_graph(site), given)
    motion = next(st for st in stages() if st.name == "motion")
    assert ctx.time_origin is None
    made = motion.work(ctx)
    assert ctx.config == {"motion": {"chatter_window": 0.5}}  # read, never written to
    assert ctx.resolved["motion"] == {"chatter_window": 0.5}  # min_on None: from the sensor type, not written
    assert isinstance(ctx.time_origin, TimeOrigin)  # found on first use, kept on the context
    assert made["motion"].height == 6


def test_the_run_record_holds_the_resolved_sections_and_the_time_origin(hallway, tmp_path):
    res = run_pipeline(
        hallway, tmp_path / "run", trackers=["hmm1"], config={"motion": {"chatter_window": 0.5}}, rrd=False
    )
    record = tomllib.loads((tmp_path / "run" / "run.toml").read_text())
    assert res.ok
    assert record["motion"]["chatter_window"] == 0.5 and "hmm1" in record and "scores" in record
    assert record["time"]["source"]
    again = run_pipeline(
        hallway, tmp_path / "again", trackers=["hmm1"], config=runner.load_run_config(tmp_path / "run" / "run.toml")
    )
    assert tomllib.loads((tmp_path / "again" / "run.toml").read_text())["hmm1"] == record["hmm1"]
    assert again.ok


def _typed_reads(monkeypatch) -> list[str]:
    """The files typed in one read through their log (:mod:`onebit.readers.logs`), in order."""
    calls: list[str] = []
    real = logs.read_typed_csv
    monkeypatch.setattr(
        logs, "read_typed_csv", lambda path, dtypes: calls.append(Path(path).name) or real(path, dtypes)
    )
    return calls


def test_a_run_reads_each_csv_log_once(hallway, tmp_path, monkeypatch):
    """``ctx.log`` is the run's one log of a file: its time-origin step reads it, its stage
    takes that read, and nothing of it is kept after the stage."""
    site = load_site(hallway / "site.toml")
    ctx = RunContext(hallway, tmp_path, site, build_region_graph(site), {})
    log = ctx.log("motion")
    assert log is ctx.log("motion") and log.path == hallway / "motion.csv"
    calls = _typed_reads(monkeypatch)
    run_time_origin(ctx)
    assert log.holds_read and calls == ["motion.csv"]
    made = next(st for st in stages() if st.name == "motion").work(ctx)
    assert made["motion"].height == 6 and calls == ["motion.csv"] and not log.holds_read


def test_a_log_whose_stage_will_not_run_keeps_no_read(hallway, tmp_path, monkeypatch):
    (hallway / "frames.csv").write_text("t,active\n0,104\n1,\n")  # the readings come from the frames
    site = load_site(hallway / "site.toml")
    ctx = RunContext(hallway, tmp_path, site, build_region_graph(site), {})
    calls = _typed_reads(monkeypatch)
    run_time_origin(ctx)
    assert "motion.csv" in calls and not ctx.log("motion").holds_read
