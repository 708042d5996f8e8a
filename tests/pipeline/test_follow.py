"""``onebit follow``: a replayed demo scenario ends with the batch run's tables for the online
trackers and reports the delay; a growing log is followed (a cut last line is waited for, not
rejected); a crash leaves every published table readable. The clock is simulated (replays
are deterministic; no test asserts on time)."""

from __future__ import annotations

import math

import numpy as np
import polars as pl
import pytest

from onebit.core.errors import ConfigError, InputError
from onebit.datasets.catalogue import get_scenario
from onebit.pipeline.follow import FollowConfig, follow, parse_speed, read_live_table
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline
from onebit.viz.inspect import blueprint_views, entity_paths


class SimClock:
    """A simulated wall clock: ``sleep`` advances it, ``on_sleep`` may grow the logs."""

    def __init__(self, on_sleep=None, *, crash_after: int | None = None):
        self.now = 1000.0
        self.sleeps = 0
        self.on_sleep = on_sleep
        self.crash_after = crash_after

    def clock(self) -> float:
        return self.now

    def sleep(self, dt: float) -> None:
        self.sleeps += 1
        if self.crash_after is not None and self.sleeps > self.crash_after:
            raise KeyboardInterrupt("simulated crash")
        self.now += dt
        if self.on_sleep is not None:
            self.on_sleep(self.sleeps)


@pytest.fixture(scope="module")
def pir(tmp_path_factory):
    root = tmp_path_factory.mktemp("pir")
    data = get_scenario("pir14").write(
        root / "d", seed=5, duration=60.0, agents=None, drop=0.0, camera=False, params={"refractory": 4}
    )
    return root, data


def _equal(live: pl.DataFrame, batch: pl.DataFrame) -> bool:
    return (
        live.select(batch.columns)
        .sort(["track", "t"], maintain_order=True)
        .equals(batch.sort(["track", "t"], maintain_order=True))
    )


def test_replay_equals_batch_and_reports_delay(pir, tmp_path):
    _, data = pir
    clock = SimClock()
    out = tmp_path / "out"
    config = {"intruder": {"camera_position": [5.0, 2.0, 3.0]}}  # the paper's pan-tilt-zoom camera
    res = follow(
        data,
        out,
        trackers=("intruder", "intruder-naive"),
        config=config,
        options=FollowConfig(replay=20.0, poll=0.2),
        clock=clock.clock,
        sleep=clock.sleep,
    )
    assert res.run.ok, res.run.status
    # an independent batch run of the same dataset: the online rows equal its tables
    batch = run_pipeline(
        data, tmp_path / "batch", trackers=("intruder", "intruder-naive"), config=config, progress=False
    )
    cam = read_live_table(res.live, "intruder_camera")
    assert cam.height > 10 and cam.equals(pl.read_parquet(batch.out / "tables" / "intruder_camera.parquet"))
    for name in ("intruder", "intruder-naive"):
        live = read_live_table(res.live, f"{name}_tracks")
        ref = pl.read_parquet(batch.out / "tables" / f"{name}_tracks.parquet")
        assert ref.height > 10
        assert _equal(live, ref), name
        assert metric(res.report, f"{name}/online_equals_batch") == 1.0
        assert metric(res.report, f"{name}/online_estimates") == ref.height
        p50, p99 = metric(res.report, f"{name}/delay_p50"), metric(res.report, f"{name}/delay_p99")
        assert 0.0 <= p50 <= p99 and math.isfinite(p99)
    # published while the log grew: many parts, in time order, not one batch at the end
    parts = sorted((res.live / "tables" / "intruder_tracks").glob("part-*.parquet"))
    assert len(parts) >= 5
    firsts = [pl.read_parquet(p)["t"].min() for p in parts]
    assert firsts == sorted(firsts)
    it = read_live_table(res.live, "intruder_iterations")
    assert it.equals(
        pl.read_parquet(batch.out / "tables" / "intruder_iterations.parquet").select(it.columns)
    ) or np.allclose(
        it["ess"].to_numpy(), pl.read_parquet(batch.out / "tables" / "intruder_iterations.parquet")["ess"].to_numpy()
    )
    delays = read_live_table(res.live, "delays")
    assert delays.height == sum(metric(res.report, f"{n}/online_estimates") for n in ("intruder", "intruder-naive"))
    # the stream: the batch recordings' entity paths, the delays, its own layout
    rrd = res.live / "rrd" / "follow.rrd"
    paths = entity_paths(rrd)
    assert {
        "intruder/tracks/intruder",
        "intruder-naive/tracks/intruder-naive",
        "follow/delay/intruder",
        "site/boundary",
    } <= paths
    assert any(p.startswith("sensors/") for p in paths)
    assert {v.kind for v in blueprint_views(rrd)} == {"2D", "StateTimeline", "TimeSeries"}
    # the follow's own final run is the batch run: same report rows as onebit run's
    a = res.run.report.filter(pl.col("stage").is_in(["intruder", "intruder-naive"]))
    b = batch.report.filter(pl.col("stage").is_in(["intruder", "intruder-naive"]))
    assert a.equals(b)


@pytest.mark.parametrize("correct", [True, False])
def test_beams_replay_equals_batch(tmp_path, monkeypatch, correct):
    """Without the correction the tracker runs crossing by crossing (never re-run on a
    prefix); with it (the correction's programme is over the whole string) it is re-run on the
    settled prefix. Both end with the batch run's tracks."""
    import onebit.pipeline.follow as follow_module

    data = get_scenario("beams-lab").write(
        tmp_path / "d", seed=3, duration=60.0, agents=2, drop=0.0, camera=False, params={}
    )
    reruns = []
    inputs = follow_module.tracker_inputs
    monkeypatch.setattr(
        follow_module, "tracker_inputs", lambda entry, *a, **k: reruns.append(entry.name) or inputs(entry, *a, **k)
    )
    clock = SimClock()
    res = follow(
        data,
        tmp_path / "out",
        trackers=("beams",),
        config=None if correct else {"correct": {"enabled": False}},
        options=FollowConfig(replay=10.0, poll=0.25),
        clock=clock.clock,
        sleep=clock.sleep,
    )
    assert (metric(res.run.report, "correct/n") is not None) == correct  # the correction ran (or not)
    live = read_live_table(res.live, "beams_tracks")
    ref = pl.read_parquet(tmp_path / "out" / "tables" / "beams_tracks.parquet")
    assert ref.height > 5 and _equal(live, ref)
    assert metric(res.report, "beams/online_equals_batch") == 1.0
    assert len(list((res.live / "tables" / "beams_tracks").glob("part-*.parquet"))) >= 3
    assert (len(reruns) > 3) if correct else (reruns == [])


def test_a_crossing_log_is_read_incrementally(tmp_path, monkeypatch):
    """A dataset with ``crossings.csv`` (decoded crossings, no raw beams): every poll reads only
    its new lines (the whole file is read once, by the final batch run) and ``beams`` runs
    crossing by crossing, equal to the batch run."""
    import onebit.pipeline.follow as follow_module
    import onebit.pipeline.reading as reading_module
    from onebit.core.site import load_site
    from onebit.readers.beams import decode_beam_log

    src = get_scenario("beams-lab").write(
        tmp_path / "d", seed=3, duration=30.0, agents=2, drop=0.0, camera=False, params={}
    )
    data = tmp_path / "crossings-only"
    data.mkdir()
    (data / "site.toml").write_bytes((src / "site.toml").read_bytes())
    decode_beam_log(src / "beams.csv", load_site(src / "site.toml").beam_ids).crossings.write_csv(
        data / "crossings.csv"
    )
    whole, reruns = [], []
    reader, inputs = reading_module.read_crossings, follow_module.tracker_inputs
    monkeypatch.setattr(reading_module, "read_crossings", lambda *a, **k: whole.append(a[0]) or reader(*a, **k))
    monkeypatch.setattr(
        follow_module, "tracker_inputs", lambda entry, *a, **k: reruns.append(entry.name) or inputs(entry, *a, **k)
    )
    clock = SimClock()
    res = follow(
        data,
        tmp_path / "out",
        trackers=("beams",),
        config={"correct": {"enabled": False}},
        options=FollowConfig(replay=20.0, poll=0.25),
        clock=clock.clock,
        sleep=clock.sleep,
    )
    ref = pl.read_parquet(tmp_path / "out" / "tables" / "beams_tracks.parquet")
    assert ref.height > 5 and _equal(read_live_table(res.live, "beams_tracks"), ref)
    assert metric(res.report, "beams/online_equals_batch") == 1.0
    assert len(whole) == 1 and reruns == []


def test_istate_replay_equals_batch_with_a_fixed_latency(tmp_path, monkeypatch):
    """O'Kane's filter is online by design; its default raises latency_s to the whole log's time
    resolution, which a prefix cannot know: with latency_auto = false it runs stage by stage
    (never re-run on a prefix) and the rows are equal."""
    import onebit.pipeline.follow as follow_module

    data = get_scenario("istate-room").write(
        tmp_path / "d", seed=2, duration=30.0, agents=None, drop=0.0, camera=False, params={}
    )
    reruns = []
    inputs = follow_module.tracker_inputs
    monkeypatch.setattr(
        follow_module, "tracker_inputs", lambda entry, *a, **k: reruns.append(entry.name) or inputs(entry, *a, **k)
    )
    clock = SimClock()
    res = follow(
        data,
        tmp_path / "out",
        trackers=("istate",),
        config={"istate": {"latency_auto": False, "absent_after": 2.0}},  # rows in silent gaps dropped
        options=FollowConfig(replay=10.0, poll=0.5),
        clock=clock.clock,
        sleep=clock.sleep,
    )
    ref = pl.read_parquet(tmp_path / "out" / "tables" / "istate_tracks.parquet")
    assert ref.height > 10 and _equal(read_live_table(res.live, "istate_tracks"), ref)
    assert metric(res.report, "istate/online_equals_batch") == 1.0
    assert reruns == []
    assert len(list((res.live / "tables" / "istate_tracks").glob("part-*.parquet"))) >= 5
    summary = pl.read_parquet(tmp_path / "out" / "tables" / "istate_summary.parquet")
    assert ref["t"].n_unique() < summary.height  # some stages fell in a silent stretch, online too


def test_growing_log_waits_for_a_cut_line_and_ends_when_idle(pir, tmp_path, monkeypatch):
    _, src = pir
    import onebit.pipeline.reading as reading_module

    whole_reads = []  # the batch reader of the whole file: only the final batch run calls it
    batch_reader = reading_module.read_motion
    monkeypatch.setattr(
        reading_module, "read_motion", lambda *a, **k: whole_reads.append(a[0]) or batch_reader(*a, **k)
    )
    d = tmp_path / "live"
    d.mkdir()
    (d / "site.toml").write_bytes((src / "site.toml").read_bytes())
    text = (src / "motion.csv").read_bytes()
    header, body = text.split(b"\n", 1)
    # the log's first 30 s (every line is a poll or two; the truth goes on past the log's end)
    lines = [ln for ln in body.splitlines(keepends=True) if float(ln.split(b",")[0]) < 30.0]
    # a logger writing a little out of order: where two lines < 0.9 s apart straddle a slot
    # boundary (2 s), the later one comes first (the reader sorts rows up to 1 s late into place)
    t = [float(ln.split(b",")[0]) for ln in lines]
    swapped = 0
    for i in range(len(lines) - 1):
        if t[i] < t[i + 1] < t[i] + 0.9 and int(t[i] // 2) != int(t[i + 1] // 2) and (i == 0 or t[i - 1] <= t[i]):
            lines[i], lines[i + 1], t[i], t[i + 1] = lines[i + 1], lines[i], t[i + 1], t[i]
            swapped += 1
    assert swapped >= 3
    # grow the log line by line, each line in two halves (the follower must wait for the newline)
    pieces = [half for ln in lines for half in (ln[: len(ln) // 2], ln[len(ln) // 2 :])]
    (d / "motion.csv").write_bytes(header + b"\n" + pieces[0])
    # the ground truth is all there from the start: it must not make the motion log's slots final
    (d / "truth.csv").write_bytes((src / "truth.csv").read_bytes())

    def grow(k: int) -> None:
        if k < len(pieces):
            with open(d / "motion.csv", "ab") as fh:
                fh.write(pieces[k])

    clock = SimClock(grow)
    # relay chatter: an off edge followed within 1.5 s by an on edge is suppressed, so an edge is
    # final only 1.5 s (+ 1 s of reordering) after it -- the follow must wait that long
    config = {"motion": {"chatter_window": 1.5}}
    res = follow(
        d,
        tmp_path / "out",
        trackers=("intruder",),
        config=config,
        options=FollowConfig(poll=0.1, idle=2.0),
        clock=clock.clock,
        sleep=clock.sleep,
    )
    assert clock.sleeps >= len(pieces)  # it ran until the log stopped growing, then idle
    # every poll read only the bytes appended since the last one (onebit/readers/tail.py)
    assert len(whole_reads) == 1
    assert metric(res.run.report, "rejects/rows") == 0.0  # no cut line was ever read as a row
    assert metric(res.run.report, "motion/suppressed") > 0
    whole = tmp_path / "whole"  # the same log, complete, in one batch run
    whole.mkdir()
    for name in ("site.toml", "motion.csv", "truth.csv"):
        (whole / name).write_bytes((d / name).read_bytes())
    ref = run_pipeline(whole, tmp_path / "batch", trackers=("intruder",), config=config, progress=False)
    assert _equal(
        read_live_table(res.live, "intruder_tracks"), pl.read_parquet(ref.out / "tables" / "intruder_tracks.parquet")
    )
    assert metric(res.report, "intruder/online_equals_batch") == 1.0


def test_a_crash_leaves_every_published_table_readable(pir, tmp_path):
    _, data = pir
    clock = SimClock(crash_after=8)
    with pytest.raises(KeyboardInterrupt):
        follow(
            data,
            tmp_path / "out",
            trackers=("intruder",),
            options=FollowConfig(replay=10.0, poll=0.5),
            clock=clock.clock,
            sleep=clock.sleep,
        )
    live = tmp_path / "out" / "live"
    tracks = read_live_table(live, "intruder_tracks")
    assert tracks is not None and 0 < tracks.height
    assert not list(live.rglob("*.partial")) and not list(live.rglob("*.tmp*"))
    assert read_live_table(live, "delays").height == tracks.height
    # a later follow into the same OUT replaces the live folder and runs
    clock = SimClock()
    res = follow(
        data,
        tmp_path / "out",
        trackers=("intruder",),
        options=FollowConfig(replay=50.0, poll=0.5),
        clock=clock.clock,
        sleep=clock.sleep,
    )
    assert metric(res.report, "intruder/online_equals_batch") == 1.0
    # a plain run into the same OUT replaces the run's files and keeps the live folder
    before = read_live_table(live, "intruder_tracks")
    assert run_pipeline(data, tmp_path / "out", trackers=("intruder-naive",), progress=False).ok
    assert read_live_table(live, "intruder_tracks").equals(before)
    assert not (tmp_path / "out" / "tables" / "intruder_tracks.parquet").exists()


def _mcap_dataset(src, d, monkeypatch) -> bytes:
    """``d`` with ``src``'s site and its motion log as a chunked MCAP of small chunks (a logger's
    file); returns the file's bytes."""
    from onebit.readers import mcap_io

    d.mkdir()
    (d / "site.toml").write_bytes((src / "site.toml").read_bytes())
    monkeypatch.setattr(mcap_io, "CHUNK_SIZE", 2048)
    motion = pl.read_csv(src / "motion.csv", infer_schema=False)
    mcap_io.write_mcap(d / "recording.mcap", {"/motion": motion}, views=False)
    return (d / "recording.mcap").read_bytes()


def test_mcap_replay_and_growing_mcap_equal_batch(pir, tmp_path, monkeypatch):
    _, src = pir
    ref = run_pipeline(src, tmp_path / "batch", trackers=("intruder",), progress=False)
    want = pl.read_parquet(ref.out / "tables" / "intruder_tracks.parquet")
    # a replay of the recording
    d = tmp_path / "rec"
    data = _mcap_dataset(src, d, monkeypatch)
    clock = SimClock()
    res = follow(
        d,
        tmp_path / "out",
        trackers=("intruder",),
        options=FollowConfig(replay=20.0, poll=0.2),
        clock=clock.clock,
        sleep=clock.sleep,
    )
    assert len(list((res.live / "tables" / "intruder_tracks").glob("part-*.parquet"))) >= 5
    assert _equal(read_live_table(res.live, "intruder_tracks"), want)
    # the same file being written: its bytes appear in pieces that cut chunks in the middle
    g = tmp_path / "growing"
    g.mkdir()
    (g / "site.toml").write_bytes((src / "site.toml").read_bytes())
    step = max(1, len(data) // 25)
    (g / "recording.mcap").write_bytes(data[:step])

    def grow(k: int) -> None:
        (g / "recording.mcap").write_bytes(data[: (k + 1) * step])

    clock = SimClock(grow)
    res = follow(
        g,
        tmp_path / "out2",
        trackers=("intruder",),
        options=FollowConfig(poll=0.1, idle=1.0),
        clock=clock.clock,
        sleep=clock.sleep,
    )
    assert len(list((res.live / "tables" / "intruder_tracks").glob("part-*.parquet"))) >= 5
    assert _equal(read_live_table(res.live, "intruder_tracks"), want)
    assert metric(res.run.report, "rejects/rows") == 0.0


def test_options_are_checked():
    assert parse_speed("20x") == 20.0 and parse_speed("0.5X") == 0.5 and parse_speed("3") == 3.0
    for bad in ("fast", "0x", "-2x", ""):
        with pytest.raises(ConfigError, match="--replay"):
            parse_speed(bad)
    with pytest.raises(ConfigError, match="poll"):
        FollowConfig(poll=0)
    with pytest.raises(ConfigError, match="replay"):
        FollowConfig(replay=-1.0)


def test_nothing_to_follow_is_an_error(tmp_path, pir):
    _, src = pir
    d = tmp_path / "d"
    d.mkdir()
    (d / "site.toml").write_bytes((src / "site.toml").read_bytes())
    with pytest.raises(InputError, match="no log to follow"):
        follow(d, tmp_path / "out")


def test_hmm_family_lagged_replay_equals_batch(tmp_path):
    """FindingHuMo's live requirement: with ``decoding = "lagged"`` (an EATG known beforehand,
    a fixed decision lag D') the hallway replayed at high speed publishes, block by block while
    the log grows, exactly the rows ``onebit run`` with the same config writes."""
    data = get_scenario("hallway").write(
        tmp_path / "d", seed=7, duration=60.0, agents=3, drop=0.0, camera=False, params={}
    )
    names = ("findinghumo", "hmm1", "hmm2")
    config = {n: {"eatg": "layout", "decoding": "lagged"} for n in names}
    clock = SimClock()
    res = follow(
        data,
        tmp_path / "out",
        trackers=names,
        config=config,
        options=FollowConfig(replay=20.0, poll=0.25),
        clock=clock.clock,
        sleep=clock.sleep,
    )
    batch = run_pipeline(data, tmp_path / "batch", trackers=names, config=config, progress=False)
    for name in names:
        live = read_live_table(res.live, f"{name}_tracks")
        ref = pl.read_parquet(batch.out / "tables" / f"{name}_tracks.parquet")
        assert ref.height > 50, name
        assert _equal(live, ref), name
        assert metric(res.report, f"{name}/online_equals_batch") == 1.0
        p50, p99 = metric(res.report, f"{name}/delay_p50"), metric(res.report, f"{name}/delay_p99")
        assert 0.0 <= p50 <= p99 and math.isfinite(p99)
        # published while the log grew, in time order: not one batch at the end
        parts = sorted((res.live / "tables" / f"{name}_tracks").glob("part-*.parquet"))
        assert len(parts) >= 5, name
        firsts = [pl.read_parquet(p)["t"].min() for p in parts]
        assert firsts == sorted(firsts), name


# `rerun --save` writes the stream as it arrives, without the footer a saved recording has
@pytest.mark.filterwarnings("ignore:RRD file has no footer")
def test_connect_streams_to_a_rerun_server(pir, tmp_path):
    """``--connect``: a headless ``rerun`` that only listens for SDKs and saves what arrives
    (``rerun --port P --save FILE``; no viewer window) receives the follow stream."""
    import shutil
    import signal
    import socket
    import subprocess
    import sys
    import time
    from pathlib import Path

    exe = shutil.which("rerun") or str(Path(sys.executable).parent / "rerun")
    assert Path(exe).exists(), "rerun-sdk installs the rerun CLI beside python: the viewer/server this test needs"
    with socket.socket() as s:  # a free port
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    saved = tmp_path / "received.rrd"
    log = open(tmp_path / "rerun.log", "w+")
    proc = subprocess.Popen([exe, "--port", str(port), "--save", str(saved)], stdout=log, stderr=subprocess.STDOUT)
    try:
        for _ in range(200):  # until it listens (polled, not timed)
            log.seek(0)
            if "Listening for gRPC" in log.read() or proc.poll() is not None:
                break
            time.sleep(0.05)
        assert proc.poll() is None, open(tmp_path / "rerun.log").read()
        _, data = pir
        clock = SimClock()
        follow(
            data,
            tmp_path / "out",
            trackers=("intruder",),
            options=FollowConfig(replay=20.0, poll=0.5),
            connect=f"rerun+http://127.0.0.1:{port}/proxy",
            clock=clock.clock,
            sleep=clock.sleep,
        )
    finally:
        proc.send_signal(signal.SIGINT)  # the server ends its file on Ctrl-C
        proc.wait(timeout=30)
        log.close()
    got = entity_paths(saved)
    assert {"intruder/tracks/intruder", "follow/delay/intruder", "site/boundary"} <= got
    assert got == entity_paths(tmp_path / "out" / "live" / "rrd" / "follow.rrd")  # what the file sink has


def _listening_on(port: int) -> set[str]:
    """The local addresses a TCP socket listens on at ``port`` (Linux: /proc/net/tcp, tcp6)."""
    import ipaddress
    from pathlib import Path

    found = set()
    for table, size in (("/proc/net/tcp", 4), ("/proc/net/tcp6", 16)):
        if not Path(table).exists():
            continue
        for line in Path(table).read_text().splitlines()[1:]:
            local, state = line.split()[1], line.split()[3]
            addr, hexport = local.split(":")
            if state == "0A" and int(hexport, 16) == port:  # 0A: LISTEN
                raw = bytes.fromhex(addr)
                raw = b"".join(raw[i : i + 4][::-1] for i in range(0, size, 4))  # host-order words
                found.add(str(ipaddress.ip_address(raw)))
    return found


def _served_ports(lines: list[str]) -> tuple[str, int, int]:
    """(page URL, page port, stream port) from a follow's ``web viewer`` lines."""
    import re

    url = next(ln.split("web viewer: ", 1)[1] for ln in lines if "web viewer: " in ln)
    m = next(m for ln in lines if (m := re.search(r"ports (\d+) \(page\) and (\d+) \(stream\)", ln)))
    return url, int(m[1]), int(m[2])


@pytest.mark.skipif(not __import__("os").path.exists("/proc/net/tcp"), reason="reads Linux's /proc/net/tcp")
def test_two_serve_web_follows_side_by_side_on_free_ports_listen_on_localhost_only(pir, tmp_path):
    """Two ``follow --serve-web`` with ``--web-port 0 --grpc-port 0`` at once: four distinct
    ports, each listened on by 127.0.0.1 only, both pages served; all closed at the end."""
    import urllib.request

    from onebit.viz.live import WebServe

    _, data = pir
    outer_lines: list[str] = []
    inner_lines: list[str] = []
    seen: dict = {}

    def look(_sleeps: int) -> None:  # inside the inner follow: both serving, look at all four ports
        if seen:
            return
        for name, lines in (("outer", outer_lines), ("inner", inner_lines)):
            url, web, grpc = _served_ports(lines)
            with urllib.request.urlopen(url, timeout=10) as r:
                page = r.read().decode()
            seen[name] = (web, grpc, _listening_on(web), _listening_on(grpc), r.status, "re_viewer.js" in page)

    def start_inner(_sleeps: int) -> None:
        if not seen:
            inner = SimClock(on_sleep=look)
            follow(
                data,
                tmp_path / "inner",
                trackers=("intruder",),
                options=FollowConfig(replay=20.0, poll=0.5),
                serve_web=WebServe(web_port=0, grpc_port=0),
                echo=inner_lines.append,
                clock=inner.clock,
                sleep=inner.sleep,
            )

    outer = SimClock(on_sleep=start_inner)
    follow(
        data,
        tmp_path / "outer",
        trackers=("intruder",),
        options=FollowConfig(replay=20.0, poll=0.5),
        serve_web=WebServe(web_port=0, grpc_port=0),
        echo=outer_lines.append,
        clock=outer.clock,
        sleep=outer.sleep,
    )
    ports = [p for name in ("outer", "inner") for p in seen[name][:2]]
    assert len(set(ports)) == 4, ports
    for name in ("outer", "inner"):
        web, grpc, web_addrs, grpc_addrs, status, is_viewer = seen[name]
        assert web_addrs == {"127.0.0.1"} and grpc_addrs == {"127.0.0.1"}, (name, web_addrs, grpc_addrs)
        assert status == 200 and is_viewer, name
    for p in ports:  # the follows ended: nothing listens any more (the page servers were stopped)
        assert _listening_on(p) == set(), p


@pytest.mark.parametrize("flag", ["--web-port", "--grpc-port"])
def test_a_port_in_use_is_one_line_naming_the_port_and_the_flag(pir, tmp_path, capsys, flag):
    import socket

    from onebit.cli import main

    _, data = pir
    (tmp_path / "out" / "live").mkdir(parents=True)
    (tmp_path / "out" / "live" / "kept.txt").write_text("a previous follow's live outputs")
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        other = "--grpc-port" if flag == "--web-port" else "--web-port"
        argv = ["follow", str(data), "--out", str(tmp_path / "out"), "--replay", "20x", "--serve-web"]
        rc = main([*argv, flag, str(port), other, "0"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert err == [
        f"onebit: error: {flag} {port}: port {port} is already in use on 127.0.0.1 (another follow "
        f"--serve-web, or a Rerun viewer?); choose another with {flag} N, or {flag} 0 for a free one"
    ]
    assert (tmp_path / "out" / "live" / "kept.txt").exists()  # refused before OUT/live is replaced


def test_the_page_server_taking_a_port_in_use_names_it(tmp_path):
    """The page's server (the ``rerun`` child) finding its port taken after the check: the same error."""
    import socket

    from onebit.viz.live import PortInUseError, start_web_viewer

    with socket.socket() as taken:  # bound, not listening: the child's bind fails, a connect would too
        taken.bind(("127.0.0.1", 0))
        port = taken.getsockname()[1]
        with pytest.raises(PortInUseError, match=f"--web-port {port}: port {port} is already in use"):
            start_web_viewer("127.0.0.1", port, "rerun+http://127.0.0.1:9/proxy", log=tmp_path / "web.log")


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"web_port": 70000}, "--web-port 70000: expected a port in 0..65535"),
        ({"grpc_port": -1}, "--grpc-port -1: expected a port"),
        ({"bind": "localhost"}, "--bind 'localhost': expected an IP address"),
        ({"web_port": 9000, "grpc_port": 9000}, "both 9000"),
    ],
)
def test_web_serve_options_are_checked(kwargs, message):
    from onebit.viz.live import WebServe

    with pytest.raises(ConfigError, match=message):
        WebServe(**kwargs)
    assert WebServe().bind == "127.0.0.1" and WebServe().local_only
