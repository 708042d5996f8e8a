"""A run folder is one transaction: never a mixture of two runs, whatever kills the run.

:func:`onebit.core.writers.folder_transaction` is tested on its own, then the runner under
SIGKILL: a run of dataset B into the folder of a complete run of dataset A is killed just
before each rename of the swap and at seeded random renames before it (every rename onebit
does goes through ``os.replace``, so "killed before rename ``n``" covers every state the
folder can be seen in). After each kill the folder must be A's run, unchanged, or marked
``INCOMPLETE`` (which ``onebit report`` refuses); the next run cleans up the dead run's work
folder and temporary files.
"""

from __future__ import annotations

import json
import os
import random
import select
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from onebit.core import writers
from onebit.core.errors import ConfigError, InputError
from onebit.datasets.beams_sim import write_beams_dataset
from onebit.pipeline.report import load_report
from onebit.pipeline.runner import RUN_ENTRIES, run_pipeline

# --------------------------------------------------------------------------- folder_transaction


def _tree(folder: Path) -> dict[str, tuple[int, int]]:
    """Every file under ``folder``: relative path -> (size, mtime in ns)."""
    return {
        str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns)
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def test_transaction_replaces_selected_entries_and_keeps_others(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "tables").mkdir()
    (out / "tables" / "old.parquet").write_text("old")
    (out / "run.toml").write_text("old")
    (out / "notes.txt").write_text("mine")
    with writers.folder_transaction(out, replaces=RUN_ENTRIES.__contains__) as work:
        assert work.parent == out and work.name.startswith(writers.WORK_PREFIX)
        (work / "tables").mkdir()
        (work / "tables" / "new.parquet").write_text("new")
        (work / "run.toml").write_text("new")
        assert (out / "run.toml").read_text() == "old"  # nothing visible until the end
    assert sorted(os.listdir(out)) == ["notes.txt", "run.toml", "tables"]
    assert os.listdir(out / "tables") == ["new.parquet"] and (out / "run.toml").read_text() == "new"


def test_transaction_that_fails_leaves_the_folder_as_it_was(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "run.toml").write_text("old")
    before = _tree(out)
    with pytest.raises(RuntimeError):
        with writers.folder_transaction(out) as work:
            (work / "run.toml").write_text("new")
            raise RuntimeError("stage crashed")
    assert _tree(out) == before and sorted(os.listdir(out)) == ["run.toml"]


def test_transaction_removes_what_dead_processes_left(tmp_path):
    out = tmp_path / "out"
    dead = _dead_pid()
    (out / f"{writers.WORK_PREFIX}{dead}" / "rrd").mkdir(parents=True)
    (out / f"{writers.OLD_PREFIX}{dead}").mkdir()
    (out / "rrd").mkdir()
    (out / "rrd" / f".camera.rrd.{dead}.partial").write_text("half")
    (out / "rrd" / f".beams.rrd.{os.getppid()}.partial").write_text("a live process's")  # kept
    with writers.folder_transaction(out, replaces=lambda n: False) as work:
        (work / "run.toml").write_text("x")
    assert sorted(os.listdir(out)) == ["rrd", "run.toml"]
    assert os.listdir(out / "rrd") == [f".beams.rrd.{os.getppid()}.partial"]


def test_a_second_writer_is_refused_while_the_first_holds_the_folder(tmp_path):
    with writers.folder_transaction(tmp_path / "out"):
        with pytest.raises(InputError, match="another onebit process"):
            with writers.folder_transaction(tmp_path / "out"):
                pass


def test_a_file_is_not_a_folder(tmp_path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(InputError, match="not a folder"):
        with writers.folder_transaction(tmp_path / "f"):
            pass


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


# --------------------------------------------------------------------------- the runner


@pytest.fixture(scope="module")
def datasets(tmp_path_factory):
    """Two small datasets of different sites: A (the lab, with truth) and B (the building,
    beams only, so that the many runs of the kill test stay quick)."""
    root = tmp_path_factory.mktemp("tx")
    a = write_beams_dataset(root / "A", "beams-lab", seed=1, duration=30.0, agents=2, camera=False)
    full_b = write_beams_dataset(root / "B-full", "beams-building", seed=2, duration=30.0, camera=False)
    a_small, b = root / "A-small", root / "B"
    for src, dst in ((a, a_small), (full_b, b)):
        dst.mkdir()
        for name in ("site.toml", "beams.csv"):
            shutil.copy(src / name, dst / name)
    return a, a_small, b


def test_a_stage_that_now_fails_leaves_no_output_of_the_previous_run(datasets, tmp_path):
    a, _, _ = datasets
    data = tmp_path / "data"
    shutil.copytree(a, data)
    out = tmp_path / "run"
    assert run_pipeline(data, out, trackers=("beams",), progress=False).ok
    assert (out / "tables" / "truth.parquet").exists() and (out / "rrd" / "truth.rrd").exists()
    (data / "run.toml").write_text("[beams]\npolicy = 'nope'\n")
    with pytest.raises(ConfigError, match="policy"):  # refused before anything is written
        run_pipeline(data, out, trackers=("beams",), progress=False)
    assert (out / "tables" / "truth.parquet").exists()
    (data / "run.toml").unlink()
    (data / "truth.csv").write_text("time,who\n1,2\n")  # the truth stage now fails
    res = run_pipeline(data, out, trackers=("beams",), progress=False)
    assert res.status["truth"].startswith("failed") and not res.ok
    assert not (out / "tables" / "truth.parquet").exists() and not (out / "rrd" / "truth.rrd").exists()
    assert (out / "tables" / "beams_tracks.parquet").exists()
    assert 'truth = "failed:' in (out / "run.toml").read_text()
    assert not [p for p in out.rglob("*") if p.name.startswith(".")]


SERVER = textwrap.dedent(
    """
    import json, os, signal, sys
    from onebit.pipeline.runner import run_pipeline   # imported once; every run is a forked child
    # what a run imports on first use, imported here once (a forked child would import it again)
    import networkx, PIL.Image, pyarrow, rerun, scipy.optimize, scipy.spatial

    for line in sys.stdin:
        cmd = json.loads(line)
        pid = os.fork()
        if pid == 0:
            calls = [0]
            real = os.replace

            def replace(src, dst, *args, **kwargs):  # every rename of onebit goes through os.replace
                calls[0] += 1
                if calls[0] == cmd["kill_at"]:
                    os.kill(os.getpid(), signal.SIGKILL)
                return real(src, dst, *args, **kwargs)

            os.replace = replace
            code = 0
            try:
                run_pipeline(cmd["dataset"], cmd["out"], trackers=("beams",), progress=False)
            except BaseException:
                code = 3
            with open(cmd["count"], "w") as fh:
                fh.write(str(calls[0]))
            os._exit(code)
        _, status = os.waitpid(pid, 0)
        killed = os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL
        print(json.dumps({"killed": killed, "pid": pid}), flush=True)
    """
)


class Server:
    """A process that imported onebit once and forks one child per run (SIGKILLed on cue)."""

    def __init__(self) -> None:
        env = dict(os.environ, RERUN_ANALYTICS="0")
        self.proc = subprocess.Popen(
            [sys.executable, "-c", SERVER], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env
        )

    def run(self, dataset: Path, out: Path, kill_at: int, count: Path) -> dict:
        self.proc.stdin.write(
            json.dumps({"dataset": str(dataset), "out": str(out), "kill_at": kill_at, "count": str(count)}) + "\n"
        )
        self.proc.stdin.flush()
        ready, _, _ = select.select([self.proc.stdout], [], [], 120)
        assert ready, "the forked run did not finish"
        return json.loads(self.proc.stdout.readline())

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait(timeout=30)


def test_killed_runs_leave_the_previous_run_or_an_incomplete_mark_never_a_mixture(datasets, tmp_path):
    _, a, b = datasets
    out = tmp_path / "run"
    server = Server()
    try:
        count = tmp_path / "count"
        run_pipeline(a, tmp_path / "probe", trackers=("beams",), progress=False)
        old_entries = len(os.listdir(tmp_path / "probe"))
        assert not server.run(b, tmp_path / "probe", 0, count)["killed"]
        renames = int(count.read_text())  # renames of a whole run over A's: the last ones are the swap
        swap = 1 + old_entries + len(os.listdir(tmp_path / "probe"))  # INCOMPLETE written, old out, new in
        first = renames - swap + 1  # the rename that writes INCOMPLETE
        rng = random.Random(17)
        inside = {first, first + 1, first + old_entries, first + old_entries + 1, renames}  # each step of the swap
        points = sorted(inside | set(rng.sample(range(1, first), 2)))  # and while the stages run
        run_pipeline(a, out, trackers=("beams",), progress=False)
        marked = 0
        for n in points:
            before = _tree(out)
            assert server.run(b, out, n, count)["killed"], n
            if writers.is_incomplete(out):
                marked += 1
                with pytest.raises(InputError, match="incomplete run folder"):
                    load_report(out)
                run_pipeline(a, out, trackers=("beams",), progress=False)  # the next run repairs it
            else:
                visible = {k: v for k, v in _tree(out).items() if not k.startswith(".")}
                assert visible == {k: v for k, v in before.items() if not k.startswith(".")}, (
                    f"mixed after a kill before rename {n}"
                )
                assert load_report(out).height > 0
        assert marked == len([n for n in points if n > first])  # killed after INCOMPLETE was written: marked
    finally:
        server.close()
    res = run_pipeline(b, out, trackers=("beams",), progress=False)
    assert res.ok and f'dataset = "{b.resolve()}"' in (out / "run.toml").read_text()
    assert not [p for p in out.rglob("*") if p.name.startswith(".")], "debris of dead runs left behind"
