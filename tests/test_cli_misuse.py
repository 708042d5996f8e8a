"""``onebit`` used carelessly: every misuse ends in one clear message and an exit code, never a
Python traceback (exit 2: bad input, refused before anything is written; exit 1: a run that
did not do what was asked; the traceback of a bug is kept in a file for a bug report)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from onebit.cli import main
from onebit.commands import run as run_command
from onebit.core import writers
from onebit.datasets.beams_sim import write_beams_dataset
from onebit.pipeline import runner


@pytest.fixture(scope="module")
def lab(tmp_path_factory) -> Path:
    return write_beams_dataset(
        tmp_path_factory.mktemp("lab") / "data", "beams-lab", seed=4, duration=30.0, agents=2, camera=False
    )


@pytest.fixture
def data(lab, tmp_path) -> Path:
    d = tmp_path / "data"
    shutil.copytree(lab, d)
    return d


def run_cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    return code, out, err


def test_out_that_is_a_file(data, tmp_path, capsys):
    (tmp_path / "f").write_text("x")
    code, _, err = run_cli(capsys, "run", data, "--out", tmp_path / "f", "--trackers", "beams")
    assert code == 2 and "OUT is a file" in err


@pytest.mark.parametrize("where", [".", "sub"])
def test_out_in_the_dataset_is_refused_and_the_dataset_untouched(data, capsys, where):
    before = (data / "run.toml").read_text()
    code, _, err = run_cli(capsys, "run", data, "--out", data / where, "--trackers", "beams")
    assert code == 2 and "dataset folder" in err
    assert (data / "run.toml").read_text() == before and not (data / "sub").exists() and not (data / "tables").exists()


def test_dataset_inside_out_and_foreign_out_are_refused(data, tmp_path, capsys):
    code, _, err = run_cli(capsys, "run", data, "--out", tmp_path, "--trackers", "beams")
    assert code == 2 and "inside OUT" in err
    foreign = tmp_path / "mine"
    foreign.mkdir()
    (foreign / "thesis.tex").write_text("precious")
    code, _, err = run_cli(capsys, "run", data, "--out", foreign, "--trackers", "beams")
    assert code == 2 and "thesis.tex" in err and sorted(os.listdir(foreign)) == ["thesis.tex"]


def test_symlink_out_of_the_dataset_is_refused_naming_it(data, tmp_path, capsys):
    secret = tmp_path / "secret.txt"
    secret.write_text("root:x:0:0:root:/root:/bin/bash\n")
    (data / "beams.csv").unlink()
    (data / "beams.csv").symlink_to(secret)
    code, _, err = run_cli(capsys, "run", data, "--out", tmp_path / "run", "--trackers", "beams")
    assert code == 2 and "beams.csv" in err and "symlink" in err and "root:x" not in err
    assert not (tmp_path / "run" / "run.toml").exists()


def test_rerun_disabled_in_the_environment_still_writes_recordings(data, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("RERUN", "0")
    code, _, _ = run_cli(capsys, "run", data, "--out", tmp_path / "run", "--trackers", "beams")
    assert code == 0 and (tmp_path / "run" / "rrd" / "beams.rrd").stat().st_size > 0
    assert os.environ["RERUN"] == "0"


@pytest.mark.parametrize("where", ["config", "dataset"])
def test_misspelt_section_names_the_known_ones(data, tmp_path, capsys, where):
    bad = tmp_path / "run.toml" if where == "config" else data / "run.toml"
    bad.write_text('[beam]\npolicy = "lifo"\n')
    argv = ["run", data, "--out", tmp_path / "run", "--trackers", "beams"] + (
        ["--config", bad] if where == "config" else []
    )
    code, _, err = run_cli(capsys, *argv)
    assert (
        code == 2 and "unknown section [beam]" in err and "'beams'" in err and "'scores'" in err and "'correct'" in err
    )
    assert not (tmp_path / "run").exists()


def test_top_level_key_and_bad_value_in_config(data, tmp_path, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_text('policy = "lifo"\n')
    code, _, err = run_cli(capsys, "run", data, "--out", tmp_path / "run", "--config", cfg)
    assert code == 2 and "'policy' is outside any section" in err
    cfg.write_text("[scores]\ncrossing_tolerance_s = nan\n")
    code, _, err = run_cli(capsys, "run", data, "--out", tmp_path / "run", "--config", cfg)
    assert code == 2 and "[scores]" in err and "crossing_tolerance_s" in err
    cfg.write_bytes(b'[beams]\npolicy = "\xff"\n')
    code, _, err = run_cli(capsys, "run", data, "--out", tmp_path / "run", "--config", cfg)
    assert code == 2 and "not UTF-8" in err and "c.toml:2" in err


def test_a_finished_run_toml_repeats_the_run(data, tmp_path, capsys):
    assert run_cli(capsys, "run", data, "--out", tmp_path / "a", "--trackers", "beams")[0] == 0
    code, _, _ = run_cli(
        capsys, "run", data, "--out", tmp_path / "b", "--trackers", "beams", "--config", tmp_path / "a" / "run.toml"
    )
    assert code == 0 and 'policy = "fifo"' in (tmp_path / "b" / "run.toml").read_text()


def test_nothing_to_do_is_an_error_and_out_is_left_as_it_was(data, tmp_path, capsys):
    for name in ("beams.csv", "truth.csv", "truth_crossings.csv"):
        (data / name).unlink()
    code, _, err = run_cli(capsys, "run", data, "--out", tmp_path / "run")
    assert code == 2 and "nothing to do: no input could be read" in err and "no beams.csv" in err
    assert not (tmp_path / "run" / "run.toml").exists()


def test_a_tracker_asked_for_that_cannot_run(data, tmp_path, capsys):
    code, _, err = run_cli(capsys, "run", data, "--out", tmp_path / "run", "--trackers", "intruder")
    assert code == 1 and "tracker 'intruder' was asked for" in err
    assert "problems = [" in (tmp_path / "run" / "run.toml").read_text()


def test_huge_bad_line_gives_bounded_console_and_run_toml(data, tmp_path, capsys):
    (data / "beams.csv").write_bytes((data / "beams.csv").read_bytes() + b'1,"a,' + b"z" * 3_000_000)
    code = main(["run", str(data), "--out", str(tmp_path / "run"), "--trackers", "beams"])
    out, err = capsys.readouterr()
    assert code == 0
    assert max(len(line) for line in (out + err).splitlines()) < 2000
    assert (tmp_path / "run" / "run.toml").stat().st_size < 20_000


@pytest.mark.parametrize("duration", ["nan", "-5", "0", "inf"])
def test_simulate_with_a_bad_duration(tmp_path, capsys, duration):
    code, _, err = run_cli(capsys, "simulate", "beams-lab", tmp_path / "d", "--duration", duration, "--no-camera")
    assert code == 2 and "--duration" in err and not (tmp_path / "d").exists()


def test_simulate_replaces_an_earlier_dataset_whole(tmp_path, capsys):
    d = tmp_path / "d"
    assert run_cli(capsys, "simulate", "beams-lab", d, "--duration", "20", "--no-camera")[0] == 0
    (d / "camera.mp4").write_bytes(b"stale video of an earlier simulation")
    assert run_cli(capsys, "simulate", "pir4", d, "--duration", "20")[0] == 0
    names = sorted(p.name for p in d.iterdir())
    assert "beams.csv" not in names and "camera.mp4" not in names and "motion.csv" in names
    assert not [n for n in names if n.startswith(".onebit-") and n != ".onebit-dataset"]


def test_simulate_into_a_foreign_folder_is_refused(tmp_path, capsys):
    d = tmp_path / "d"
    d.mkdir()
    (d / "notes.txt").write_text("mine")
    code, _, err = run_cli(capsys, "simulate", "beams-lab", d, "--duration", "20", "--no-camera")
    assert code == 2 and "notes.txt" in err and sorted(os.listdir(d)) == ["notes.txt"]


def test_verify_path_with_a_label_that_is_no_beam(data, tmp_path, capsys):
    assert run_cli(capsys, "run", data, "--out", tmp_path / "run", "--trackers", "beams")[0] == 0
    code, _, err = run_cli(capsys, "verify-path", tmp_path / "run", "--story", "a zz^-1")
    assert code == 2 and "'zz'" in err and "beams are a, b, c, d" in err


def test_report_refuses_incomplete_and_unfinished_folders(data, tmp_path, capsys):
    out = tmp_path / "run"
    assert run_cli(capsys, "run", data, "--out", out, "--trackers", "beams")[0] == 0
    (out / writers.INCOMPLETE).write_text("cut")
    code, _, err = run_cli(capsys, "report", out)
    assert code == 2 and "incomplete run folder" in err
    fresh = tmp_path / "fresh"
    (fresh / f"{writers.WORK_PREFIX}99999999").mkdir(parents=True)
    code, _, err = run_cli(capsys, "report", fresh)
    assert code == 2 and "no finished run here yet" in err
    # the next run repairs the interrupted folder
    assert run_cli(capsys, "run", data, "--out", out, "--trackers", "beams")[0] == 0
    assert run_cli(capsys, "report", out)[0] == 0


def test_site_that_is_not_utf8_or_has_nan_fps(data, tmp_path, capsys):
    site = (data / "site.toml").read_bytes()
    (data / "site.toml").write_bytes(site + b"\n# caf\xe9\n")
    code, _, err = run_cli(capsys, "run", data, "--out", tmp_path / "run")
    assert code == 2 and "not UTF-8" in err
    (data / "site.toml").write_bytes(site.replace(b"fps = ", b"fps = nan #"))
    code, _, err = run_cli(capsys, "run", data, "--out", tmp_path / "run")
    assert code == 2 and "camera.fps" in err


def test_a_bug_gives_one_line_and_keeps_the_traceback(data, tmp_path, capsys, monkeypatch):
    def broken(*args, **kwargs):
        raise RuntimeError("boom")

    monkeypatch.setattr(runner, "_read_mcaps", broken)
    code, _, err = run_cli(capsys, "run", data, "--out", tmp_path / "run", "--trackers", "beams")
    assert code == 1 and "internal error: RuntimeError: boom" in err
    tb = tmp_path / "run" / "logs" / "run.traceback.txt"
    assert str(tb) in err and "RuntimeError: boom" in tb.read_text()
    assert "ok = false" in (tmp_path / "run" / "run.toml").read_text()
    monkeypatch.setattr(run_command, "load_report", broken)
    code, _, err = run_cli(capsys, "report", tmp_path / "run")
    assert code == 1 and "internal error" in err
    kept = Path(err.split("the traceback is in ")[1].split(";")[0])
    assert "RuntimeError: boom" in kept.read_text()
    kept.unlink()


def test_interrupt_leaves_out_as_it_was(data, tmp_path, capsys, monkeypatch):
    out = tmp_path / "run"
    assert run_cli(capsys, "run", data, "--out", out, "--trackers", "beams")[0] == 0
    before = sorted(p.name for p in out.rglob("*"))

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(runner, "_read_mcaps", interrupted)
    code, _, err = run_cli(capsys, "run", data, "--out", out, "--trackers", "beams")
    assert code == 130 and "interrupted" in err
    assert sorted(p.name for p in out.rglob("*")) == before


# --------------------------------------------------------------------------- inputs that used to exhaust memory (#26 item 8)


def test_random_bytes_as_a_log_fail_its_stage_naming_the_file(data, tmp_path, capsys):
    """Random bytes as ``beams.csv``: refused as not text, naming the file and line (200 MB of them
    made a 4 GB MemoryError)."""
    (data / "beams.csv").write_bytes(bytes(range(256)) * 1000)
    code, _, err = run_cli(capsys, "run", data, "--out", tmp_path / "run", "--no-rrd")
    status = (tmp_path / "run" / "run.toml").read_text()
    assert code == 1 and "stage(s) failed" in err
    assert "beams.csv:2: not a text file" in status  # line 1 is bytes 0-9: ASCII


def test_instants_past_the_limit_are_refused_at_load(tmp_path, capsys):
    """``[proximity] instants = 10000000000`` in a dataset's run.toml aborted the process (exit 134)."""
    from onebit.datasets.proximity_sim import SCENARIO_SPECS

    d = SCENARIO_SPECS["proximity-line"].write(tmp_path / "prox", seed=1, params={})
    toml = (d / "run.toml").read_text() if (d / "run.toml").exists() else ""
    (d / "run.toml").write_text("[proximity]\ninstants = 10000000000\n" + toml.replace("[proximity]", "[old]"))
    code, _, err = run_cli(capsys, "run", d, "--out", tmp_path / "run", "--no-rrd")
    assert code == 2 and "ProximityConfig.instants = 10000000000; allowed range: [0, 10000000]" in err


def test_an_mcap_cut_in_its_header_is_an_unreadable_input(data, tmp_path, capsys):
    from onebit.readers.mcap_io import MAGIC

    alone = tmp_path / "alone"
    alone.mkdir()
    shutil.copy(data / "site.toml", alone / "site.toml")
    (alone / "log.mcap").write_bytes(MAGIC + b"\x01\x05")
    code, _, err = run_cli(capsys, "run", alone, "--out", tmp_path / "run")
    assert code == 2 and "unreadable input: log.mcap: unreadable: truncated in its MCAP header" in err
    assert "nothing to do" not in err
    (data / "log.mcap").write_bytes(MAGIC[:5])  # beside readable logs: the run goes on, not ok, one reject
    code, _, err = run_cli(capsys, "run", data, "--out", tmp_path / "run2", "--trackers", "beams", "--no-rrd")
    assert code == 1 and 'mcap:log.mcap" = "failed: unreadable' in (tmp_path / "run2" / "run.toml").read_text()
