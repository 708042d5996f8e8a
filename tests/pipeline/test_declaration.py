"""The declaration (``onebit/pipeline/stages.py``) is the one list both runners run: a stage
added there is run by ``onebit run`` and by ``onebit follow``; every fact about a tracker is on
its entry (how it runs live included), and every tracker is in the import contracts."""

from __future__ import annotations

import ast
import tomllib
from dataclasses import dataclass
from pathlib import Path

import polars as pl
import pytest

import onebit.pipeline.follow as follow_module
from onebit.core.tables import TRACKS, conform
from onebit.datasets.catalogue import get_scenario
from onebit.pipeline import stages as declaration
from onebit.pipeline.context import RunContext, Stage
from onebit.pipeline.follow import FollowConfig, follow, read_live_table
from onebit.pipeline.online import BATCH, LAGGED, ONLINE, PREFIX, Live
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline
from onebit.pipeline.stages import TRACKERS, TrackerEntry
from onebit.trackers.base import TrackerSpec

ROOT = Path(__file__).resolve().parents[2]


def _with_a_motion_count(calls: list[int]):
    """The declared stages plus one, right after ``motion``, that counts the accepted edges so
    far (polled: ``onebit follow`` runs it on every poll); ``calls`` gets the count of each call."""
    declared = declaration.stages

    def work(ctx: RunContext) -> dict[str, pl.DataFrame]:
        n = ctx.tables["motion"].height
        calls.append(n)
        return {"motion_count": pl.DataFrame({"edges": [n]})}

    extra = Stage("motion_count", ("motion",), ("motion_count",), lambda ctx: None, work, polled=True)

    def stages(trackers=TRACKERS):
        out = declared(trackers)
        at = next(i for i, st in enumerate(out) if st.name == "motion") + 1
        return [*out[:at], extra, *out[at:]]

    return stages


class _Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def clock(self) -> float:
        return self.now

    def sleep(self, dt: float) -> None:
        self.now += dt


@pytest.fixture(scope="module")
def pir(tmp_path_factory):
    root = tmp_path_factory.mktemp("declared")
    return get_scenario("pir14").write(
        root / "d", seed=5, duration=30.0, agents=None, drop=0.0, camera=False, params={"refractory": 4}
    )


def test_a_stage_added_to_the_declaration_is_run_by_run_and_by_follow(pir, tmp_path, monkeypatch):
    calls: list[int] = []
    monkeypatch.setattr(declaration, "stages", _with_a_motion_count(calls))
    res = run_pipeline(pir, tmp_path / "run", trackers=("intruder",), rrd=False, progress=False)
    assert res.status["motion_count"].startswith("ok")
    total = pl.read_parquet(tmp_path / "run" / "tables" / "motion_count.parquet")["edges"][0]
    assert total > 10 and calls == [total]

    calls.clear()
    clock = _Clock()
    done = follow(
        pir,
        tmp_path / "follow",
        trackers=("intruder",),
        options=FollowConfig(replay=10.0, poll=0.5),
        clock=clock.clock,
        sleep=clock.sleep,
    )
    assert done.run.status["motion_count"].startswith("ok")  # the final batch run
    live, last = calls[:-1], calls[-1]
    assert last == total  # the batch run's call, on the whole log
    assert len(live) >= 3 and live == sorted(live) and live[0] < live[-1] <= total  # on every poll, as the log grew


def test_follow_names_no_tracker():
    """``follow`` runs trackers as their entries declare (``TrackerEntry.live``): no tracker's
    name is a string of its code."""
    tree = ast.parse(Path(follow_module.__file__).read_text())
    docstrings = {
        id(node.body[0].value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef)
        and node.body
        and isinstance(node.body[0], ast.Expr)
        and isinstance(node.body[0].value, ast.Constant)
    }
    strings = {
        n.value
        for n in ast.walk(tree)
        if isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in docstrings
    }
    assert not strings & {e.name for e in TRACKERS}


def test_every_live_mode_is_declared_whole():
    """online and lagged trackers have a stepper; lagged and prefix ones say which events close
    a re-run's rows; a mode outside the four is refused."""
    modes = {e.name: e.live.mode for e in TRACKERS}
    assert set(modes.values()) <= {ONLINE, LAGGED, PREFIX, BATCH}
    assert modes["intruder"] == ONLINE and modes["intruder-naive"] == PREFIX and modes["residents"] == BATCH
    for e in TRACKERS:
        if e.live.mode in (ONLINE, LAGGED):
            assert e.live.stepper is not None, e.name
        if e.live.mode in (LAGGED, PREFIX):
            assert e.live.events, e.name
        if e.live.mode != BATCH:
            assert e.live.note, e.name
    with pytest.raises(Exception, match="Live.mode"):
        Live("sometimes")
    with pytest.raises(Exception, match="events"):
        Live(PREFIX, "per event")


def test_a_tracker_stage_needs_what_its_spec_needs():
    by_name = {st.name: st for st in declaration.stages()}
    for e in TRACKERS:
        assert by_name[e.name].needs == e.spec.needs, e.name


def test_every_tracker_is_in_the_independence_contract():
    """Every tracker package (each entry's, and each folder of ``onebit/trackers``) is in the
    import-linter contract "A tracker never imports another tracker" (pyproject.toml)."""
    contracts = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"]
    independent = [c for c in contracts if c["type"] == "independence"]
    assert len(independent) == 1
    modules = set(independent[0]["modules"])
    of_entries = {".".join(e.spec.run.__module__.split(".")[:3]) for e in TRACKERS}
    folders = {f"onebit.trackers.{p.parent.name}" for p in (ROOT / "onebit" / "trackers").glob("*/__init__.py")}
    assert of_entries <= folders
    assert folders == modules, f"missing: {sorted(folders - modules)}; not a tracker: {sorted(modules - folders)}"


def _edges(inputs: dict, site, config) -> dict[str, pl.DataFrame]:
    """A dummy tracker: one estimate at the origin per accepted motion edge."""
    m = inputs["motion"].filter(pl.col("on"))
    tracks = pl.DataFrame(
        {"tracker": "edges", "track": "a", "t": m["t"], "x": 0.0, "y": 0.0},
        schema_overrides={"tracker": pl.String, "track": pl.String},
    )
    return {"tracks": conform(tracks, TRACKS)}


@dataclass(frozen=True, kw_only=True)
class _EdgesConfig:
    pass


def test_a_tracker_declared_prefix_runs_live_by_its_declaration(pir, tmp_path):
    """A tracker ``follow`` has never heard of, declared ``live=Live(PREFIX, ...)``, is re-run on
    the settled prefix at the polls and ends equal to the batch run's rows."""
    entry = TrackerEntry(
        TrackerSpec(name="edges", needs=("motion",), config=_EdgesConfig, run=_edges),
        lambda tracker, tables, site, rg: ([], {}),
        live=Live(PREFIX, "per edge", events=("motion",)),
    )
    clock = _Clock()
    lines: list[str] = []
    res = follow(
        pir,
        tmp_path / "follow",
        trackers=("edges",),
        options=FollowConfig(replay=10.0, poll=0.5),
        clock=clock.clock,
        sleep=clock.sleep,
        echo=lines.append,
        tracker_entries=(*TRACKERS, entry),
    )
    assert "  edges: online, per edge" in lines
    batch = pl.read_parquet(tmp_path / "follow" / "tables" / "edges_tracks.parquet")
    live = read_live_table(res.live, "edges_tracks")
    assert batch.height > 5 and live.sort("t").equals(batch.sort("t"))
    assert len(list((res.live / "tables" / "edges_tracks").glob("part-*.parquet"))) >= 3
    assert metric(res.report, "edges/online_equals_batch") == 1.0
