"""``onebit follow`` under live faults (docs/live.md, "Faults"): a log rotated or truncated and
rewritten by a restarting logger, a line cut and never finished, the logger's clock stepped
back, the disk filling. In each case the rows published before the fault stay as they were and
the follow ends with the batch run's tables on the log as followed. The clock is simulated
(``SimClock``: each ``sleep`` runs the logger's next action)."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import polars as pl
import pytest

from onebit import cli
from onebit.core import writers
from onebit.core.errors import DiskFullError, is_disk_full
from onebit.datasets.catalogue import get_scenario
from onebit.pipeline.follow import FollowConfig, follow, read_live_table
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline

CHUNK = 24  # lines a logger action appends (320 lines: 14 appends, 3 to 6 parts published before a fault)


class SimClock:
    """A simulated wall clock: ``sleep`` advances it and runs the logger's action for that poll."""

    def __init__(self, actions):
        self.now = 1000.0
        self.sleeps = 0
        self.actions = actions

    def clock(self) -> float:
        return self.now

    def sleep(self, dt: float) -> None:
        self.now += dt
        if self.sleeps < len(self.actions):
            self.actions[self.sleeps]()
        self.sleeps += 1


@pytest.fixture(scope="module")
def pir(tmp_path_factory):
    root = tmp_path_factory.mktemp("pir")
    data = get_scenario("pir14").write(
        root / "d", seed=5, duration=60.0, agents=None, drop=0.0, camera=False, params={"refractory": 4}
    )
    header, body = (data / "motion.csv").read_bytes().split(b"\n", 1)
    return data, header + b"\n", body.splitlines(keepends=True)


def _live(src: Path, d: Path, header: bytes | None = None) -> Path:
    """A dataset folder with ``src``'s site (and a motion log holding only ``header``)."""
    d.mkdir()
    (d / "site.toml").write_bytes((src / "site.toml").read_bytes())
    if header is not None:
        (d / "motion.csv").write_bytes(header)
    return d


def _append(path: Path, data: bytes):
    def act() -> None:
        with open(path, "ab") as fh:
            fh.write(data)

    return act


def _appends(path: Path, lines: list[bytes]) -> list:
    return [_append(path, b"".join(lines[i : i + CHUNK])) for i in range(0, len(lines), CHUNK)]


def _follow(d: Path, out: Path, actions: list, notes: list[str]):
    clock = SimClock(actions)
    res = follow(
        d,
        out,
        trackers=("intruder",),
        options=FollowConfig(poll=0.5, idle=2.0),
        clock=clock.clock,
        sleep=clock.sleep,
        echo=notes.append,
    )
    assert clock.sleeps > len(actions)  # every action ran, then the log stayed idle
    return res


def _batch(tmp: Path, src: Path, motion: bytes):
    """``onebit run`` on the log as it was followed (one file)."""
    whole = _live(src, tmp / "whole")
    (whole / "motion.csv").write_bytes(motion)
    return run_pipeline(whole, tmp / "batch", trackers=("intruder",), progress=False)


def _equal_to_batch(res, ref) -> None:
    live = read_live_table(res.live, "intruder_tracks")
    batch = pl.read_parquet(ref.out / "tables" / "intruder_tracks.parquet")
    assert batch.height > 10
    assert live.select(batch.columns).sort(["track", "t"]).equals(batch.sort(["track", "t"]))
    assert metric(res.report, "intruder/online_equals_batch") == 1.0
    rejects = pl.read_parquet(res.run.out / "tables" / "rejects.parquet")
    assert rejects.equals(pl.read_parquet(ref.out / "tables" / "rejects.parquet"))


class _Parts:
    """The published parts (bytes) at one moment, to check later that they were kept as they were."""

    def __init__(self, out: Path):
        self.folder = out / "live" / "tables" / "intruder_tracks"
        self.seen: dict[Path, bytes] = {}

    def take(self) -> None:
        self.seen = {p: p.read_bytes() for p in sorted(self.folder.glob("part-*.parquet"))}

    def kept(self) -> bool:
        return len(self.seen) >= 2 and all(p.read_bytes() == b for p, b in self.seen.items())


def test_a_rotated_log_is_followed_into_its_new_file(pir, tmp_path):
    """Renamed and a new file started: the old file is read to its end (its unfinished last line
    taken, a reject naming its line), then the new file from its start (its header dropped)."""
    src, header, lines = pir
    d = _live(src, tmp_path / "live", header)
    log = d / "motion.csv"
    r = len(lines) // 2
    cut = lines[r][: lines[r].rindex(b",")]  # "t,sensor": the logger stopped mid-line
    parts = _Parts(tmp_path / "out")

    def rotate() -> None:
        parts.take()
        os.replace(log, d / "motion.csv.1")
        log.write_bytes(header + b"".join(lines[r + 1 : r + 1 + CHUNK]))

    actions = [*_appends(log, lines[:r]), _append(log, cut), rotate]
    actions += _appends(log, lines[r + 1 + CHUNK :])
    notes: list[str] = []
    res = _follow(d, tmp_path / "out", actions, notes)
    assert any("rotated" in n for n in notes)
    assert metric(res.report, "follow/log_restarts") == 1.0
    assert parts.kept()
    followed = header + b"".join(lines[:r]) + cut + b"\n" + b"".join(lines[r + 1 :])
    ref = _batch(tmp_path, src, followed)
    _equal_to_batch(res, ref)
    rejects = pl.read_parquet(res.run.out / "tables" / "rejects.parquet")
    # the cut line (header = line 1); its sensor's next edge then changes no state
    assert rejects.row(0)[:3] == ("motion.csv", r + 2, "too few fields (2 of 3)")
    assert rejects.height <= 2


@pytest.mark.parametrize("how", ["truncated", "rewritten"])
def test_a_log_restarted_in_place_is_read_again_from_its_start(pir, tmp_path, how):
    """A restarting logger truncates its file and writes its header and new lines: seen when the
    file is shorter than what was read, and when it is as long or longer but its bytes under the
    last line read changed. The log followed is the old lines, then the new ones."""
    src, header, lines = pir
    d = _live(src, tmp_path / "live", header)
    log = d / "motion.csv"
    r = len(lines) // 3
    # rewritten: the new file is at once longer than what was read (a size check alone misses it)
    k = 2 if how == "truncated" else r + 5
    parts = _Parts(tmp_path / "out")

    def restart() -> None:
        parts.take()
        with open(log, "wb") as fh:  # truncates
            fh.write(header + b"".join(lines[r : r + k]))

    actions = [*_appends(log, lines[:r]), restart, *_appends(log, lines[r + k :])]
    notes: list[str] = []
    res = _follow(d, tmp_path / "out", actions, notes)
    assert any("truncated or rewritten" in n for n in notes)
    assert metric(res.report, "follow/log_restarts") == 1.0
    assert parts.kept()
    ref = _batch(tmp_path, src, header + b"".join(lines))  # no line lost, none read twice
    _equal_to_batch(res, ref)
    assert metric(res.run.report, "rejects/rows") == 0.0


def test_a_line_never_finished_is_taken_at_the_end(pir, tmp_path):
    """The log ends in a line without its newline: when the follow ends (idle) it is taken as
    the batch reader takes a file's last line -- here cut mid-field, so a reject naming it."""
    src, header, lines = pir
    d = _live(src, tmp_path / "live", header)
    log = d / "motion.csv"
    cut = lines[-1][: lines[-1].rindex(b",")]
    actions = [*_appends(log, lines[:-1]), _append(log, cut)]
    res = _follow(d, tmp_path / "out", actions, [])
    ref = _batch(tmp_path, src, header + b"".join(lines[:-1]) + cut)  # the same bytes, read once
    _equal_to_batch(res, ref)
    rejects = pl.read_parquet(res.run.out / "tables" / "rejects.parquet")
    assert rejects.rows() == [("motion.csv", len(lines) + 1, "too few fields (2 of 3)", cut.decode())]


def test_a_clock_stepped_back_rejects_its_rows_until_it_catches_up(pir, tmp_path):
    """From line r on (t ~ 20 s), the logger stamps 10 s earlier: every row more than 1 s behind the latest
    accepted one is a "goes backwards" reject (counted, said once), as in the batch run; the
    rows published before are kept and later rows are accepted once the clock has caught up."""
    src, header, lines = pir
    d = _live(src, tmp_path / "live", header)
    log = d / "motion.csv"
    r = len(lines) // 3
    assert float(lines[r].split(b",")[0]) - 10.0 > float(lines[0].split(b",")[0])  # not before the first stamp
    stepped = []
    for ln in lines[r:]:
        t, rest = ln.split(b",", 1)
        stepped.append(f"{float(t) - 10.0:.3f}".encode() + b"," + rest)
    parts = _Parts(tmp_path / "out")
    actions = [*_appends(log, lines[:r]), parts.take, *_appends(log, stepped)]
    notes: list[str] = []
    res = _follow(d, tmp_path / "out", actions, notes)
    assert parts.kept()
    ref = _batch(tmp_path, src, header + b"".join(lines[:r] + stepped))
    _equal_to_batch(res, ref)
    back = metric(res.report, "follow/rows_rejected_backwards")
    assert 0 < back < len(stepped)  # rejected until the clock passed the old latest time again
    assert back == metric(res.run.report, "rejects/rows")
    said = [n for n in notes if "clock stepped back" in n]
    assert len(said) == 1 and f"motion.csv:{r + 2}:" in said[0]


# --------------------------------------------------------------------------- a full disk


def test_disk_full_is_recognised_in_what_writers_raise():
    """The errors a full device gives (``/dev/full``): Python's OSError with errno, and the
    Rust writers' text without one (polars: "No space left on device (os error 28)")."""
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full here")
    df = pl.DataFrame({"a": list(range(10_000))})
    seen = []
    for write in (
        lambda: df.write_parquet("/dev/full"),
        lambda: df.write_csv("/dev/full"),
        lambda: Path("/dev/full").write_bytes(b"x" * 100_000),
    ):
        with pytest.raises(Exception) as info:  # noqa: B017, PT011 - each library raises its own type
            write()
        seen.append(is_disk_full(info.value))
    assert seen == [True, True, True]
    assert not is_disk_full(OSError(errno.EACCES, "Permission denied"))
    assert not is_disk_full(ValueError("bad value"))


@pytest.fixture
def disk_fills(monkeypatch):
    """``fill(after)``: the ``after``+1-th Parquet write writes half a file, then the device is full."""

    def fill(after: int) -> list[int]:
        calls = [0]
        real = pl.DataFrame.write_parquet

        def write_parquet(self, file, *args, **kwargs):
            calls[0] += 1
            if calls[0] > after:
                Path(file).write_bytes(b"PAR1 half a file")
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            return real(self, file, *args, **kwargs)

        monkeypatch.setattr(pl.DataFrame, "write_parquet", write_parquet)
        return calls

    return fill


def _no_half_files(folder: Path) -> None:
    names = [p.name for p in folder.rglob("*")]
    assert not [n for n in names if ".tmp" in n or n.endswith(".partial") or n.startswith(".onebit-")], names


def test_atomic_writer_turns_a_full_disk_into_one_error(tmp_path, disk_fills):
    target = tmp_path / "t.parquet"
    writers.write_parquet(pl.DataFrame({"a": [1]}), target)
    disk_fills(0)
    with pytest.raises(DiskFullError) as info:
        writers.write_parquet(pl.DataFrame({"a": [2]}), target)
    assert str(target) in str(info.value) and "no space left" in str(info.value)
    assert pl.read_parquet(target)["a"].to_list() == [1]  # the old content kept
    _no_half_files(tmp_path)


def test_disk_full_during_follow(pir, tmp_path, disk_fills, capsys):
    """The CLI stops with one line and a non-zero exit; the parts published before are intact,
    no half file is left, OUT holds no half run."""
    src, _, _ = pir
    out = tmp_path / "out"
    calls = disk_fills(6)
    code = cli.main(
        ["follow", str(src), "--out", str(out), "--trackers", "intruder", "--replay", "100x", "--poll", "0.05"]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code != 0 and calls[0] == 7
    assert len(err) == 1 and err[0].startswith("onebit: error: ") and "no space left on the device" in err[0]
    live = out / "live"
    parts = list((live / "tables").rglob("part-*.parquet"))
    assert len(parts) == 6 and all(pl.read_parquet(p).height for p in parts)
    assert read_live_table(live, "intruder_tracks").height > 0
    assert not (out / "tables").exists() and not (out / "run.toml").exists()
    _no_half_files(out)


def test_disk_full_during_run_keeps_the_previous_run(pir, tmp_path, disk_fills, capsys):
    src, _, _ = pir
    out = tmp_path / "out"
    assert cli.main(["run", str(src), "--out", str(out), "--trackers", "intruder"]) == 0
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    capsys.readouterr()
    disk_fills(3)
    code = cli.main(["run", str(src), "--out", str(out), "--trackers", "intruder"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code != 0
    assert len(err) == 1 and "no space left on the device" in err[0]
    after = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert after == before
    _no_half_files(out)
