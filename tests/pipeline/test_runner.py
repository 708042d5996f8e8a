"""End to end: simulate -> onebit run -> report, .rrd files, failures and MCAP input."""

from __future__ import annotations

import os
import shutil
import tomllib
from pathlib import Path

import polars as pl
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader

from onebit._testing.workers import NoConfig, bad_input_run, bug_run, where
from onebit.cli import main
from onebit.core.errors import MAX_MESSAGE, ConfigError, OnebitError
from onebit.datasets.beams_sim import write_beams_dataset
from onebit.datasets.builtin import builtin_site_path
from onebit.pipeline.report import load_report, metric
from onebit.pipeline.runner import check_sections, load_run_config, run_pipeline
from onebit.pipeline.stages import TRACKERS, TrackerEntry, stages, tracker_names
from onebit.trackers.base import TrackerSpec
from onebit.viz.inspect import entity_paths, store_ids, verify


@pytest.fixture(scope="module")
def lab_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("lab")
    data = write_beams_dataset(root / "data", "beams-lab", seed=3, duration=30.0, agents=2, drop=0.0, camera=True)
    res = run_pipeline(data, root / "run")
    return data, res


def test_lab_run_without_drops_recovers_everything(lab_run):
    _, res = lab_run
    assert res.ok, res.status
    rep = res.report
    assert metric(rep, "crossings/decoded_match") == 1.0
    assert metric(rep, "crossings/spurious") == 0.0
    assert metric(rep, "beams/agent_count_error") == 0.0
    assert metric(rep, "camera/truth_error_rel") < 0.02
    assert metric(rep, "rejects/rows") == 0.0
    acc = metric(rep, "beams/assignment_accuracy")
    assert 0.0 <= acc <= 1.0
    # the truth positions reproduce the simulator's own crossing list
    assert metric(rep, "truth/crossings_from_positions") == 1.0


def test_run_folder_contents(lab_run):
    _, res = lab_run
    out = res.out
    for name in ("crossings", "truth", "beams_tracks", "beams_assignment", "beams_agents", "camera_truth", "rejects"):
        assert (out / "tables" / f"{name}.parquet").exists(), name
    report = pl.read_csv(out / "report.csv")
    assert report.columns[:4] == ["stage", "metric", "value", "unit"]
    assert load_report(out).height == report.height
    run_toml = (out / "run.toml").read_text()
    assert 'policy = "fifo"' in run_toml and "[stages]" in run_toml
    assert not list(out.rglob("*.tmp")) and not list(out.rglob("*.partial"))
    tracks = pl.read_parquet(out / "tables" / "beams_tracks.parquet")
    assert tracks["x"].null_count() == tracks.height and tracks["region"].null_count() == 0


def test_rrd_files_verify_and_hold_site_truth_tracks(lab_run):
    _, res = lab_run
    rrds = sorted((res.out / "rrd").glob("*.rrd"))
    assert {p.stem for p in rrds} >= {"crossings", "truth", "camera", "beams", "scores"}
    ids = set()
    paths: set[str] = set()
    for p in rrds:
        verify(p)
        ids.update(store_ids(p))
        paths |= entity_paths(p)
    assert len({rid for _, rid in ids}) == 1  # one recording id across the stages
    for want in (
        "site/boundary",
        "site/beams/a",
        "site/regions/r1",
        "truth/agent1",
        "beams/tracks/agent1",
        "sensors/a",
    ):
        assert any(q == want or q.startswith(want + "/") for q in paths), want
    assert any(q.startswith("beams/occupancy/") for q in paths)


def test_cli_report_and_logs_info(lab_run, capsys):
    data, res = lab_run
    assert main(["report", str(res.out)]) == 0
    out = capsys.readouterr().out
    assert "crossings/decoded_match" in out and "beams/assignment_accuracy" in out
    assert main(["logs", "info", str(data / "beams.csv")]) == 0
    assert "beams.csv" in capsys.readouterr().out


def test_failing_stage_keeps_the_others(lab_run, tmp_path, capsys):
    data, _ = lab_run
    bad = tmp_path / "data"
    shutil.copytree(data, bad)
    (bad / "camera.mp4").write_bytes(b"\x00\x01not a video" * 100)
    code = main(["run", str(bad), "--out", str(tmp_path / "run")])
    assert code == 1
    text = capsys.readouterr().out
    assert "camera: FAILED" in text and "camera.mp4" in text
    out = tmp_path / "run"
    assert (out / "tables" / "beams_tracks.parquet").exists()
    assert not (out / "rrd" / "camera.rrd").exists()
    rep = load_report(out)
    assert metric(rep, "crossings/decoded_match") == 1.0
    assert 'camera = "failed:' in (out / "run.toml").read_text()


def test_skipped_stages_say_why(tmp_path):
    site = builtin_site_path("lab")
    d = tmp_path / "data"
    d.mkdir()
    shutil.copy(site, d / "site.toml")
    (d / "crossings.csv").write_text("t,beam,direction\n1,d,1\n2,c,1\n3,q,1\n")
    res = run_pipeline(d, tmp_path / "run")
    assert res.status["truth"].startswith("skipped: no truth.csv")
    assert res.status["camera"].startswith("skipped: no camera.mp4")
    assert res.status["beams"].startswith("ok")
    assert metric(res.report, "rejects/rows") == 1.0
    rej = pl.read_parquet(tmp_path / "run" / "tables" / "rejects.parquet")
    assert rej.row(0)[:2] == ("crossings.csv", 4)


def test_a_tracker_whose_every_input_failed_is_skipped_not_run_on_nothing(lab_run, tmp_path):
    # istate reads any of motion, proximity, crossings, beam_events; when the only one the
    # dataset has fails, istate must say so instead of reporting 0 elements and 0 m^2
    data, _ = lab_run
    bad = tmp_path / "data"
    shutil.copytree(data, bad)
    site = (bad / "site.toml").read_text()
    if "targets" not in site:
        (bad / "site.toml").write_text("targets = 2\n" + site)
    (bad / "beams.csv").write_text(
        "t,beam,pair,blocked\n1,a,a,1\n1e11,a,b,1\n5,a,a,0\n"
        + "".join(f"{1.7e9 + i},a,a,{i % 2}\n" for i in range(400))
    )
    res = run_pipeline(bad, tmp_path / "run", trackers=["istate"])
    assert res.status["crossings"].startswith("failed")
    assert (
        res.status["istate"]
        == "skipped: none of its input tables (motion, proximity, crossings, beam_events) was produced by an earlier stage"
    )


def test_mcap_dataset_gives_the_same_crossings(lab_run, tmp_path, monkeypatch):
    import onebit.readers.mcap_io as mcap_io

    data, res = lab_run
    d = tmp_path / "data"
    d.mkdir()
    shutil.copy(data / "site.toml", d / "site.toml")
    monkeypatch.setattr(mcap_io, "CHUNK_SIZE", 256 * 1024)  # chunks of a quarter of the default: several here
    assert main(["logs", "convert", str(data), str(d / "recording.mcap")]) == 0
    r2 = run_pipeline(d, tmp_path / "run")
    assert r2.ok, r2.status
    a = pl.read_parquet(res.out / "tables" / "crossings.parquet")
    b = pl.read_parquet(tmp_path / "run" / "tables" / "crossings.parquet")
    assert a.equals(b)
    # a truncated recording keeps the complete chunks before the cut and names the file in rejects
    raw = (d / "recording.mcap").read_bytes()
    with open(d / "recording.mcap", "rb") as fh:
        chunks = make_reader(fh).get_summary().chunk_indexes
    assert len(chunks) >= 2  # chunked (CHUNK_SIZE of messages each), zstd
    (d / "recording.mcap").write_bytes(raw[: chunks[1].chunk_start_offset + (chunks[1].chunk_length // 2)])
    r3 = run_pipeline(d, tmp_path / "run3")
    rej = pl.read_parquet(tmp_path / "run3" / "tables" / "rejects.parquet")
    assert rej.filter(pl.col("reason").str.contains("truncated"))["source"].to_list() == ["recording.mcap"]
    assert metric(r3.report, "rejects/rows") >= 1.0
    assert 0 < pl.read_parquet(tmp_path / "run3" / "tables" / "beam_events.parquet").height


def test_drops_reduce_decoded_match(tmp_path):
    data = write_beams_dataset(tmp_path / "data", "beams-building", seed=5, duration=120.0, drop=0.3, camera=False)
    res = run_pipeline(data, tmp_path / "run")
    sim = pl.read_csv(data / "truth_crossings.csv")
    dropped = sim["dropped"].sum() / sim.height
    assert 0 < dropped < 1
    assert metric(res.report, "crossings/decoded_match") == pytest.approx(1 - dropped, abs=1e-9)


def test_broken_site_is_a_clear_cli_error(tmp_path, capsys):
    d = tmp_path / "data"
    d.mkdir()
    (d / "site.toml").write_text("[boundary]\npolygon = [[0, 0], [1, 0]]\n")
    assert main(["run", str(d), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert "site.toml" in err and "boundary.polygon" in err


# --------------------------------------------------------------------------- inputs checked before anything is written


def test_known_sections_are_the_stage_names(tmp_path):
    names = [st.name for st in stages()]
    assert {"motion", "proximity", "correct", "scores", *tracker_names()} <= set(names)
    with pytest.raises(ConfigError) as info:
        check_sections({"beam": {"policy": "lifo"}}, stages(), source="run.toml")
    assert "unknown section [beam]" in str(info.value) and str(sorted(names)) in str(info.value)
    check_sections({"beams": {"policy": "lifo"}, "scores": {}}, stages(), source="run.toml")


def test_a_run_record_as_config_gives_its_stage_sections(lab_run, tmp_path):
    _, res = lab_run
    cfg = load_run_config(res.out / "run.toml")
    assert "stages" not in cfg and "summary" not in cfg and cfg["beams"]["policy"] == "fifo"
    check_sections(cfg, stages(), source="run.toml")


def test_reusing_out_says_what_it_replaces_and_mixes_nothing(lab_run, tmp_path):
    data, _ = lab_run
    out = tmp_path / "run"
    said: list[str] = []
    run_pipeline(data, out, trackers=("beams",), echo=said.append)
    first = tomllib.loads((out / "run.toml").read_text())["recording_id"]
    (out / "notes.txt").write_text("mine")
    run_pipeline(data, out, trackers=("beams",), config={"correct": {"enabled": False}}, echo=said.append)
    assert any(f"the previous run (recording {first}): replacing it" in s and "notes.txt" in s for s in said)
    rid = tomllib.loads((out / "run.toml").read_text())["recording_id"]
    assert rid != first and not (out / "tables" / "corrected_crossings.parquet").exists()
    assert {rec for p in (out / "rrd").glob("*.rrd") for _, rec in store_ids(p)} == {rid}
    assert (out / "notes.txt").read_text() == "mine"


VALID_RUN_TOML = b'[beams]\npolicy = "lifo"\n[scores]\ncrossing_tolerance_s = 0.5\n[correct]\nenabled = false\n'


@st.composite
def _mutated_run_toml(draw) -> bytes:
    data = bytearray(VALID_RUN_TOML)
    for _ in range(draw(st.integers(1, 4))):
        pos = draw(st.integers(0, len(data)))
        op = draw(st.sampled_from(["flip", "insert", "delete", "nest"]))
        if op == "flip" and data:
            data[min(pos, len(data) - 1)] ^= 1 << draw(st.integers(0, 7))
        elif op == "insert":
            data[pos:pos] = draw(
                st.sampled_from([b"[", b"]", b'"', b"\n", b"\xff", b"nan", b"-inf", b"= 1", b"[beam]\n", b"x" * 5000])
            )
        elif op == "delete":
            del data[pos : pos + draw(st.integers(1, 6))]
        else:
            k = draw(st.sampled_from([3, 3000]))
            data[pos:pos] = b"\nz = " + b"[" * k + b"]" * k + b"\n"
    return bytes(data)


@settings(max_examples=100, deadline=None)
@given(blob=st.one_of(st.binary(max_size=200), _mutated_run_toml()))
def test_run_toml_fuzz_only_onebit_errors_and_bounded(tmp_path_factory, blob):
    p = tmp_path_factory.mktemp("cfg") / "run.toml"
    p.write_bytes(blob)
    try:
        check_sections(load_run_config(p), stages(), source=p)
    except OnebitError as exc:
        assert len(str(exc)) <= MAX_MESSAGE + 200


def test_a_dataset_run_toml_motion_and_scores_sections_are_used(tmp_path):
    """Issue #26: ``[motion]`` and ``[scores]`` of the dataset's own ``run.toml`` were validated but
    ignored (``ctx.config.get`` instead of the section), so ``period = 0.5`` ran at 1.0 (the
    ``frames`` table it sized is gone; ``chatter_window`` shows the same)."""
    d = tmp_path / "data"
    d.mkdir()
    shutil.copy(builtin_site_path("hallway"), d / "site.toml")
    (d / "motion.csv").write_text("t,sensor,value\n0,104,1\n1.6,104,0\n2.1,103,1\n3.7,103,0\n4.2,102,1\n5.8,102,0\n")
    (d / "run.toml").write_text("[motion]\nchatter_window = 0.6\n")  # 1.6 off -> 2.1 on of 104/103: not the same sensor
    res = run_pipeline(d, tmp_path / "run", trackers=["hmm1"])
    assert res.status["motion"].startswith("ok")
    assert tomllib.loads((tmp_path / "run" / "run.toml").read_text())["motion"]["chatter_window"] == 0.6
    (d / "motion.csv").write_text("t,sensor,value\n0,104,1\n1.6,104,0\n2.1,104,1\n3.7,104,0\n")
    res = run_pipeline(d, tmp_path / "run2", trackers=["hmm1"])
    assert metric(res.report, "motion/suppressed") == 2.0  # the 1.6 off / 2.1 on pair: within 0.6 s


@pytest.fixture(scope="module")
def side_run(lab_run, tmp_path_factory):
    """The lab dataset run again as ``onebit run --no-rrd --cores 2`` (trackers worked side by
    side, one of them in a worker) with every table a worker makes passed back through a file
    (``SPILL_BYTES`` 0): (run folder, what it printed, the spill files before and after)."""
    import contextlib
    import io
    import tempfile

    import onebit.pipeline.detach as detach

    data, _ = lab_run
    out = tmp_path_factory.mktemp("side") / "side"
    printed = io.StringIO()
    spills = lambda: set(Path(tempfile.gettempdir()).glob("onebit-table-*.arrow"))  # noqa: E731
    before = spills()
    with pytest.MonkeyPatch.context() as mp, contextlib.redirect_stdout(printed):
        mp.setattr(detach, "SPILL_BYTES", 0)
        assert main(["run", str(data), "--out", str(out), "--no-rrd", "--cores", "2"]) == 0
    return out, printed.getvalue(), before, spills()


def _same_tables_and_report(out: Path, ref: Path) -> None:
    """Every table (but the timings) and the report (but seconds) of ``out`` are ``ref``'s."""
    names = sorted(p.name for p in (ref / "tables").glob("*.parquet"))
    assert sorted(p.name for p in (out / "tables").glob("*.parquet")) == names
    for name in names:
        if name == "timings.parquet":  # seconds differ from run to run
            continue
        assert pl.read_parquet(out / "tables" / name).equals(pl.read_parquet(ref / "tables" / name)), name
    seconds = pl.col("unit") != "s"
    assert load_report(out).filter(seconds).equals(load_report(ref).filter(seconds))


def test_no_rrd_writes_the_same_tables_and_report_without_recordings(lab_run, side_run):
    """``--no-rrd`` (here with ``--cores 2``, :func:`side_run`): no recording, the tables and
    report of the run with recordings."""
    _, res = lab_run
    out, printed, _, _ = side_run
    assert "Rerun recordings: none (--no-rrd)" in printed
    assert not (out / "rrd").exists()
    _same_tables_and_report(out, res.out)
    record = tomllib.loads((out / "run.toml").read_text())
    assert record["timing"]["rrd"] is False
    assert all(v["viz_s"] < 0.01 for k, v in record["timing"].items() if isinstance(v, dict))


def test_run_record_times_work_recording_and_writing_of_every_stage(lab_run, tmp_path):
    _, res = lab_run
    record = tomllib.loads((res.out / "run.toml").read_text())
    timing = record["timing"]
    ran = [name for name, state in record["stages"].items() if state.startswith("ok")]
    assert set(ran) <= set(timing) and timing["rrd"] is True
    for name in ran:
        assert {"work_s", "viz_s", "write_s"} <= set(timing[name]) and min(timing[name].values()) >= 0.0
        assert f"({timing[name]['work_s']:.2f} s)" in record["stages"][name]  # the status shows the work alone
    assert timing["entered_unix"] <= (res.out / "run.toml").stat().st_mtime
    assert 0.0 <= timing["worker_cpu_s"] <= timing["run_cpu_s"]  # a lab run's stages start no worker
    # a run record given back as --config ignores the timing (not a stage section)
    assert "timing" not in load_run_config(res.out / "run.toml")


def test_istate_beyond_its_stage_bound_is_skipped_saying_why(lab_run, tmp_path):
    data, full = lab_run
    assert full.status["istate"].startswith("ok")  # 30 s = 31 stages: within the default bound
    res = run_pipeline(data, tmp_path / "bounded", config={"istate": {"max_stages": 10}}, rrd=False)
    reason = res.status["istate"]
    assert reason.startswith("skipped") and "max_stages = 10" in reason and "stages of period_s = 1 s" in reason
    assert res.ok  # not asked for by name: the others ran, the run is ok
    asked = run_pipeline(
        data, tmp_path / "asked", trackers=("istate",), config={"istate": {"max_stages": 10}}, rrd=False
    )
    assert not asked.ok and any("max_stages" in p for p in asked.problems)
    lifted = run_pipeline(
        data, tmp_path / "lifted", trackers=("istate",), config={"istate": {"max_stages": 0}}, rrd=False
    )
    assert lifted.status["istate"].startswith("ok")


def test_trackers_side_by_side_give_the_same_run(lab_run, side_run, tmp_path):
    """``--cores 2``: the trackers are worked side by side (here and in a worker process, each on
    one core); every table, the report and each stage's status are the ones of one tracker
    after another, and the worker's CPU is in the run's."""
    data, res = lab_run
    out = side_run[0]
    ran = [n for n, s in res.status.items() if s.startswith("ok") and n in {e.name for e in TRACKERS}]
    assert len(ran) >= 2, ran  # two trackers or more: one of them worked in a worker
    _same_tables_and_report(out, res.out)
    record = tomllib.loads((out / "run.toml").read_text())
    assert [s.split(" (")[0] for s in record["stages"].values()] == [s.split(" (")[0] for s in res.status.values()]
    assert record["timing"]["worker_cpu_s"] > 0.0
    with pytest.raises(ConfigError, match="cores"):
        run_pipeline(data, tmp_path / "bad", cores=-1)


def test_a_tracker_failing_beside_the_others_fails_as_it_would_alone(lab_run, tmp_path):
    """A detached tracker's error is its stage's, as in one process: an OnebitError is said as it
    is, a bug keeps its traceback in logs/; the other trackers' tables are unchanged."""
    data, _ = lab_run
    entries = (
        *TRACKERS,
        TrackerEntry(TrackerSpec(name="bug", needs=("crossings",), config=NoConfig, run=bug_run), None, None),
        TrackerEntry(TrackerSpec(name="bad", needs=("crossings",), config=NoConfig, run=bad_input_run), None, None),
    )
    runs = {
        cores: run_pipeline(
            data,
            tmp_path / f"c{cores}",
            trackers=("beams", "bug", "bad"),
            tracker_entries=entries,
            rrd=False,
            cores=cores,
        )
        for cores in (1, 3)
    }
    for cores, res in runs.items():
        assert res.status["bad"] == "failed: the crossings say nothing this tracker can use", cores
        assert res.status["bug"] == "failed: RuntimeError: a bug in the tracker", cores
        assert "a bug in the tracker" in (tmp_path / f"c{cores}" / "logs" / "bug.traceback.txt").read_text()
        assert res.status["beams"].startswith("ok")
    assert pl.read_parquet(tmp_path / "c3" / "tables" / "beams_tracks.parquet").equals(
        pl.read_parquet(tmp_path / "c1" / "tables" / "beams_tracks.parquet")
    )


def test_stages_that_share_work_stay_in_one_call():
    """hmm2 and findinghumo-flow decode the same run and share it one after the other in one
    process: a side-by-side batch keeps stages of one ``shares`` key in one call."""
    from onebit.pipeline.context import Stage
    from onebit.pipeline.detach import detach_batch

    def stage(name, key):
        return Stage(
            name,
            (),
            (f"{name}_*",),
            lambda ctx: None,
            lambda ctx: where(name),
            detach=lambda ctx: (where, (name,), key),
        )

    batch = [stage("a", None), stage("b", "decode"), stage("c", None), stage("d", "decode")]
    out = detach_batch(batch, None, 3)
    pid = {n: int(o.made[f"{n}_where"]["pid"][0]) for n, o in out.items()}
    assert pid["a"] == os.getpid()  # the first here
    assert pid["b"] == pid["d"] != os.getpid()  # the shared pair together, in a worker
    assert sorted(out) == ["a", "b", "c", "d"]


def test_hmm2_and_findinghumo_flow_share_a_key_and_others_do_not():
    from onebit.models.graph_hmm.decoding import HmmConfig
    from onebit.trackers.findinghumo.stage import SPECS, FindingHumoConfig
    from onebit.trackers.findinghumo_flow.stage import SPEC as FLOW
    from onebit.trackers.findinghumo_flow.stage import FlowConfig

    spec = {s.name: s for s in SPECS}
    flow = FLOW.shares(FlowConfig())
    assert spec["hmm2"].shares(HmmConfig()) == flow
    assert spec["hmm1"].shares(HmmConfig()) != flow
    assert FLOW.shares(FlowConfig(decoder="adaptive")) == spec["findinghumo"].shares(FindingHumoConfig())
    assert spec["hmm2"].shares(HmmConfig(decoding="lagged", eatg="layout")) is None


def test_a_workers_large_tables_come_back_through_files(lab_run, side_run):
    """Tables of SPILL_BYTES or more pass from a worker as Arrow IPC files read here (every
    table, with the bound at 0, :func:`side_run`): the same tables as one process, and no file
    is left."""
    _, res = lab_run
    out, _, before, after = side_run
    assert tomllib.loads((out / "run.toml").read_text())["stages"].keys() == res.status.keys()
    _same_tables_and_report(out, res.out)
    assert after == before
