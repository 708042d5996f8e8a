"""``onebit logs split``: a long dataset as one dataset per period, run over ``run-many`` (local
pool and Ray) with the same tables as ``onebit run`` on each part; no line lost."""

from __future__ import annotations

from pathlib import Path

import polars as pl
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.cli import main
from onebit.core.errors import ConfigError, InputError
from onebit.datasets.home_sim import write_home_dataset
from onebit.pipeline.executors import LocalPoolExecutor, RayExecutor
from onebit.pipeline.runmany import run_many
from onebit.pipeline.runner import run_pipeline
from onebit.pipeline.split import parse_period, split_dataset

TRACKERS = ("residents",)


@pytest.fixture(scope="module")
def parts(tmp_path_factory) -> Path:
    """A simulated two-resident home of 15 minutes cut into 5-minute parts."""
    root = tmp_path_factory.mktemp("split")
    write_home_dataset(root / "home", seed=2, duration=900.0)
    assert main(["logs", "split", str(root / "home"), str(root / "parts"), "--every", "5m"]) == 0
    return root


def _tables(run: Path) -> dict[str, pl.DataFrame]:
    return {p.stem: pl.read_parquet(p) for p in sorted((run / "tables").glob("*.parquet")) if p.stem != "timings"}


def test_no_line_is_lost_and_every_part_is_a_dataset(parts):
    home = parts / "home"
    folders = sorted((parts / "parts").glob("part-*"))
    assert [f.name for f in folders] == ["part-000", "part-001", "part-002"]
    for log in ("motion.csv", "truth.csv"):
        whole = (home / log).read_text().splitlines()
        cut = [line for f in folders for line in (f / log).read_text().splitlines()[1:]]
        assert cut == whole[1:]  # every line, in order, as written
        assert all((f / log).read_text().splitlines()[0] == whole[0] for f in folders)
    assert all((f / "site.toml").read_bytes() == (home / "site.toml").read_bytes() for f in folders)
    t = pl.read_csv(folders[1] / "motion.csv")["t"]
    assert t.min() >= 300.0 and t.max() < 600.0


@pytest.fixture(scope="module")
def one_run_per_part(parts, tmp_path_factory) -> dict[str, Path]:
    """``onebit run`` on each of the first two parts: {part: run folder}."""
    root = tmp_path_factory.mktemp("one")
    folders = sorted((parts / "parts").glob("part-*"))[:2]
    single = {f.name: run_pipeline(f, root / f.name, trackers=TRACKERS, rrd=False) for f in folders}
    assert all(r.status["residents"].startswith("ok") for r in single.values())
    return {name: r.out for name, r in single.items()}


@pytest.mark.parametrize("kind", ["local", "ray"])
def test_run_many_on_the_local_pool_and_ray_gives_the_tables_of_one_run_per_part(
    parts, one_run_per_part, tmp_path, request, kind
):
    folders = sorted((parts / "parts").glob("part-*"))[:2]
    if kind == "ray":
        request.getfixturevalue("ray_local")  # the session's Ray (tests/conftest.py); skips without the ray extra
    ex = RayExecutor(workers=2) if kind == "ray" else LocalPoolExecutor(workers=2)
    with ex:
        res = run_many([str(f) for f in folders], tmp_path / ex.kind, trackers=TRACKERS, executor=ex, rrd=False)
    assert res.ok, ex.kind
    for f in folders:
        got = _tables(res.out / f.name)
        want = _tables(one_run_per_part[f.name])
        assert got.keys() == want.keys(), ex.kind
        for name in want:
            assert got[name].equals(want[name]), (ex.kind, f.name, name)


def test_refusals(tmp_path):
    (tmp_path / "d").mkdir()
    with pytest.raises(InputError, match="no log to split"):
        split_dataset(tmp_path / "d", tmp_path / "o", every=60.0)
    (tmp_path / "d" / "motion.csv").write_text("t,sensor,value\n0,M1,1\n")
    (tmp_path / "d" / "log.mcap").write_bytes(b"\x89MCAP0\r\n")
    with pytest.raises(InputError, match="onebit logs convert"):
        split_dataset(tmp_path / "d", tmp_path / "o", every=60.0)
    (tmp_path / "d" / "log.mcap").unlink()
    (tmp_path / "d" / "truth.csv").write_text("time,target\n0,a\n")
    with pytest.raises(InputError, match="no 't' column"):
        split_dataset(tmp_path / "d", tmp_path / "o", every=60.0)
    (tmp_path / "d" / "truth.csv").unlink()
    split_dataset(tmp_path / "d", tmp_path / "o", every=60.0)
    with pytest.raises(InputError, match="already has parts"):
        split_dataset(tmp_path / "d", tmp_path / "o", every=60.0)
    for bad in ("0", "-1d", "1w", "x"):
        with pytest.raises(ConfigError, match="--every"):
            parse_period(bad)


def test_stamps_cut_at_midnight_and_unreadable_times_stay_with_the_line_before(tmp_path):
    d = tmp_path / "d"
    d.mkdir()
    (d / "motion.csv").write_text(
        "t,sensor,value\n"
        "2024-03-01T23:59:58,M1,1\n"
        "not a time,M1,0\n"  # goes with the line before (the part's reader rejects it)
        "2024-03-02T00:00:01,M2,1\n"
    )
    parts = split_dataset(d, tmp_path / "o", every=parse_period("1d"))
    assert [p.rows["motion.csv"] for p in parts] == [2, 1]
    assert (parts[0].path / "motion.csv").read_text().splitlines()[2] == "not a time,M1,0"


@settings(max_examples=25, deadline=None)
@given(
    st.lists(st.floats(0, 10_000, allow_nan=False), min_size=1, max_size=40),
    st.sampled_from([60.0, 600.0, 3600.0]),
)
def test_every_row_lands_in_the_part_of_its_window(tmp_path_factory, ts, every):
    d = tmp_path_factory.mktemp("d")
    ts = sorted(ts)
    (d / "motion.csv").write_text("t,sensor,value\n" + "".join(f"{t!r},M1,1\n" for t in ts))
    parts = split_dataset(d, d / "o", every=every)
    seen = []
    for p in parts:
        got = pl.read_csv(p.path / "motion.csv")["t"].to_list() if p.rows["motion.csv"] else []
        assert all(p.start <= t < p.end for t in got)
        seen += got
    assert seen == ts
