"""``onebit run-many``: dataset selection, one atomic run folder per dataset, the summary, the
same summary on every executor, failures that do not stop the others, killed workers."""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from pathlib import Path

import polars as pl
import pytest

from onebit.cli import main
from onebit.core.errors import ConfigError, InputError
from onebit.datasets.beams_sim import write_beams_dataset
from onebit.datasets.pir_sim import write_pir_dataset
from onebit.pipeline.executors import ExecutorError, LocalPoolExecutor, RayExecutor, SerialExecutor, make_executor
from onebit.pipeline.report import load_report
from onebit.pipeline.runmany import SUMMARY, commit_folder, dataset_names, find_datasets, run_many

ray = pytest.importorskip("ray", reason="the ray extra (pip install 'onebit[ray]'; make test installs it)")

TINY = ("d0", "d1", "d2")


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    """Three short beams-lab datasets, one folder without a site.toml, and a slower PIR
    dataset (its own run.toml asks for many particles) that a test can kill mid-run."""
    root = tmp_path_factory.mktemp("runmany") / "data"
    for k, name in enumerate(TINY):
        write_beams_dataset(root / name, "beams-lab", seed=k, duration=30.0, camera=False)
    (root / "empty").mkdir()
    slow = write_pir_dataset(root / "victim", "pir14", seed=1, duration=30.0)
    with open(slow / "run.toml", "a", encoding="utf-8") as fh:
        fh.write("\n[intruder]\nparticles = 10000\n")
    return root


def _some(data: Path) -> list[str]:
    """The three tiny datasets (a glob) and the folder without a site.toml."""
    return [str(data / "d*"), str(data / "empty")]


def _hidden(out: Path) -> list[str]:
    return sorted(p.name for p in out.rglob(".*"))


def _deterministic(summary: pl.DataFrame) -> pl.DataFrame:
    """Everything but wall-clock metrics (unit "s"; none for these datasets, kept for safety)."""
    return summary.filter(pl.col("unit").is_null() | (pl.col("unit") != "s"))


# --------------------------------------------------------------------------- selecting datasets


def test_find_datasets_takes_folders_globs_and_list_files(data, tmp_path):
    listing = tmp_path / "floors.txt"
    listing.write_text(
        f"# one folder per line\n{data / 'd0'}\n\n{os.path.relpath(data / 'd1', tmp_path)}  # relative to the list\n"
    )
    found = find_datasets([str(data / "d2"), str(data / "d*"), str(listing)])
    assert [p.name for p in found] == ["d2", "d0", "d1"]  # duplicates dropped, first mention kept
    assert find_datasets([str(data / "*")], out=data / "empty") == [data / n for n in (*TINY, "victim")]  # OUT left out
    with pytest.raises(InputError, match="no dataset folder matches"):
        find_datasets([str(data / "nothing*")])
    (tmp_path / "blank.txt").write_text("# nothing\n")
    with pytest.raises(InputError, match="names no folder"):
        find_datasets([str(tmp_path / "blank.txt")])


def test_run_folder_names_keep_the_day_and_floor(tmp_path):
    days = [tmp_path / "b" / d / f for d in ("day1", "day2") for f in ("floor1", "floor2")]
    assert dataset_names(days) == ["day1/floor1", "day1/floor2", "day2/floor1", "day2/floor2"]
    assert dataset_names([tmp_path / "b" / "day1" / "floor2"]) == ["floor2"]
    with pytest.raises(ConfigError, match="inside dataset 'day1'"):
        dataset_names([tmp_path / "day1", tmp_path / "day1" / "floor1"])


def test_commit_folder_replaces_a_previous_run_whole(tmp_path):
    final, tmp = tmp_path / "run", tmp_path / ".run.partial"
    (final / "tables").mkdir(parents=True)
    (final / "tables" / "old.parquet").write_text("old")
    (tmp / "tables").mkdir(parents=True)
    (tmp / "report.csv").write_text("new")
    commit_folder(tmp, final)
    assert sorted(p.relative_to(final).as_posix() for p in final.rglob("*")) == ["report.csv", "tables"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


# --------------------------------------------------------------------------- the same on every executor


@pytest.fixture(scope="module")
def serial_run(data, tmp_path_factory):
    return run_many(_some(data), tmp_path_factory.mktemp("serial") / "out", executor=SerialExecutor())


def test_summary_one_row_per_dataset_and_metric_failures_named(serial_run, data):
    res = serial_run
    assert res.summary.schema == SUMMARY
    assert not res.ok  # 'empty' has no site.toml
    status = dict(zip(res.datasets["dataset"], res.datasets["status"]))
    assert status == {"d0": "ok", "d1": "ok", "d2": "ok", "empty": "failed"}
    empty = res.summary.filter(pl.col("dataset") == "empty")
    assert empty.height == 1 and "site.toml" in empty["error"][0] and empty["metric"][0] is None
    for name in TINY:  # the summary holds each run's report, and each run folder is complete
        rows = res.summary.filter(pl.col("dataset") == name).select("stage", "metric", "value", "unit")
        assert rows.equals(load_report(res.out / name))
        assert (res.out / name / "run.toml").exists() and any((res.out / name / "rrd").glob("*.rrd"))
    assert not (res.out / "empty").exists()
    assert pl.read_csv(res.out / "summary.csv").height == res.summary.height
    assert pl.read_parquet(res.out / "summary.parquet").equals(res.summary)
    assert 'empty = "failed: ' in (res.out / "run-many.toml").read_text()
    assert _hidden(res.out) == []


def test_local_pool_and_ray_give_the_serial_summary(serial_run, data, tmp_path, ray_local):
    for ex in (LocalPoolExecutor(workers=2), RayExecutor(workers=2)):
        with ex:
            res = run_many(_some(data), tmp_path / ex.kind, executor=ex, rrd=False)
        assert _deterministic(res.summary).equals(_deterministic(serial_run.summary)), ex.kind
        assert res.datasets.select("dataset", "status", "error").equals(
            serial_run.datasets.select("dataset", "status", "error")
        )
        assert _hidden(res.out) == []
    assert ray_local.is_initialized()  # a Ray the caller started is left running


def test_a_second_run_replaces_the_run_folders_and_clears_what_a_killed_one_left(data, tmp_path):
    out = tmp_path / "out"
    first = run_many([str(data / "d0")], out)
    marker = out / "d0" / "stale.txt"
    marker.write_text("from an older run")
    (out / ".d0.partial-deadbeef-12345" / "tables").mkdir(parents=True)  # left by a killed run-many
    second = run_many([str(data / "d0")], out)
    assert first.ok and second.ok and not marker.exists()
    assert _hidden(out) == []


# --------------------------------------------------------------------------- killed workers


def _kill_when_running(out: Path, name: str, box: dict) -> threading.Thread:
    """Kill (SIGKILL) the worker process that runs dataset ``name`` as soon as its temporary
    run folder appears (the worker's pid ends the folder's name)."""

    def watch():
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            hits = list(out.glob(f".{name}.partial-*")) if out.exists() else []
            if hits:
                pid = int(hits[0].name.rsplit("-", 1)[1])
                box["final_existed"] = (out / name).exists()
                os.kill(pid, signal.SIGKILL)
                box["pid"] = pid
                return
            time.sleep(0.005)

    th = threading.Thread(target=watch, daemon=True)
    th.start()
    return th


def _killed_run(data, out, executor):
    box: dict = {}
    th = _kill_when_running(out, "victim", box)
    with executor:
        res = run_many([str(data / "victim"), *(str(data / n) for n in TINY)], out, executor=executor, rrd=False)
    th.join(5)
    assert "pid" in box, "the victim's worker was not seen running"
    assert box["final_existed"] is False  # nothing at the final place while the task ran
    return res, box["pid"]


def _worker_pid(res, name: str) -> int:
    return int(res.datasets.filter(pl.col("dataset") == name)["worker"][0].rsplit(":", 1)[1])


def test_killed_ray_worker_task_is_retried(data, tmp_path, ray_local):
    res, killed = _killed_run(data, tmp_path / "out", RayExecutor(workers=2))
    assert res.ok, res.datasets
    assert _worker_pid(res, "victim") != killed  # run again by another worker process
    assert (res.out / "victim" / "report.parquet").exists()
    assert _hidden(res.out) == []  # the killed attempt's temporary folder is gone


def test_killed_pool_worker_is_retried_on_a_fresh_pool(data, tmp_path):
    res, killed = _killed_run(data, tmp_path / "out", LocalPoolExecutor(workers=2))
    assert res.ok, res.datasets
    assert _worker_pid(res, "victim") != killed
    assert _hidden(res.out) == []


def test_killed_worker_without_retries_fails_visibly_and_leaves_no_run_folder(data, tmp_path):
    res, _ = _killed_run(data, tmp_path / "out", LocalPoolExecutor(workers=1, max_retries=0))
    status = dict(zip(res.datasets["dataset"], res.datasets["status"]))
    assert status == {"victim": "failed", "d0": "ok", "d1": "ok", "d2": "ok"}, res.datasets
    err = res.summary.filter(pl.col("dataset") == "victim")["error"][0]
    assert "worker died" in err
    assert not (res.out / "victim").exists() and _hidden(res.out) == []
    assert not res.ok


# --------------------------------------------------------------------------- the command line


def test_cli_run_many_prints_the_summary_and_exits_1_on_a_failed_dataset(data, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run-many", str(data / "d*"), "--out", str(out), "--executor", "serial", "--trackers", "beams"]) == 0
    text = capsys.readouterr().out
    assert "3 of 3 dataset(s) ok" in text and "d2" in text
    assert (
        main(
            [
                "run-many",
                str(data / "d0"),
                str(data / "empty"),
                "--out",
                str(out),
                "--executor",
                "local",
                "--workers",
                "2",
            ]
        )
        == 1
    )
    assert "failed: empty" in capsys.readouterr().out


def test_executor_options_are_checked(data, tmp_path, capsys):
    with pytest.raises(ConfigError, match="--workers"):
        make_executor("local", workers=0)
    with pytest.raises(ConfigError, match="--ray-address: only with --executor ray"):
        make_executor("local", address="auto")
    assert main(["run-many", str(data / "d0"), "--out", str(tmp_path), "--workers", "0"]) == 2
    assert "--workers" in capsys.readouterr().err


def test_ray_executor_without_ray_says_how_to_install_it(data, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    with pytest.raises(ExecutorError, match=r"pip install 'onebit\[ray\]'"):
        RayExecutor().start()
    assert main(["run-many", str(data / "d0"), "--out", str(tmp_path / "o"), "--executor", "ray"]) == 2
    assert "pip install 'onebit[ray]'" in capsys.readouterr().err
