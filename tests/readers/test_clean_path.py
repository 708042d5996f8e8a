"""The fast path of the CSV readers (one typed ``pl.read_csv`` of a clean file) against the
row-by-row path on the same bytes: equal frames and equal rejects, on random valid files and
on the same files with one fault or more injected (the fast path then steps aside or finds the
same duplicates and rows out of order)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest

from onebit.readers.beams import BEAM_COLUMNS, clean_beam_events, decode_beam_log, decode_raw_beams
from onebit.readers.motion import TOGGLE_COLUMNS, DebounceRules, clean_toggle_rows, read_motion, read_motion_csv
from onebit.readers.rows import read_clean_csv, read_csv_rows
from onebit.readers.timebase import TimeOrigin

BEAMS = ("a", "b", "c", "d")
SENSORS = ("p1", "p2", "p3")


def _beam_lines(rng, n):
    """(header, ``n`` lines) of a beam log in time order, drawn as whole columns (a large file
    in milliseconds, not one draw per field)."""
    t = np.round(np.cumsum(rng.exponential(0.05, n)), 3).tolist()
    beam, pair = rng.choice(BEAMS, n).tolist(), rng.choice(["a", "b"], n).tolist()
    rows = [f"{a},{b},{c},{d}" for a, b, c, d in zip(t, beam, pair, rng.integers(0, 2, n).tolist())]
    return ["t,beam,pair,blocked"], rows


def _toggle_lines(rng, n):
    """(header, ``n`` lines) of a motion log in time order, drawn as whole columns."""
    t = np.round(np.cumsum(rng.exponential(0.3, n)), 2).tolist()
    sensor, value = rng.choice(SENSORS, n).tolist(), rng.choice(["0", "1", "on", "off"], n).tolist()
    return ["t,sensor,value"], [f"{a},{b},{c}" for a, b, c in zip(t, sensor, value)]


#: Faults injected into a valid file's data lines: each returns the new list of lines.
FAULTS = {
    "duplicate": lambda rng, rows: rows[: len(rows) // 2] + [rows[len(rows) // 3]] + rows[len(rows) // 2 :],
    "backwards": lambda rng, rows: rows[:-1] + ["0.001" + rows[-1][rows[-1].index(",") :]],
    "slightly late": lambda rng, rows: rows[:10] + [rows[12]] + rows[10:12] + rows[13:],
    "unknown name": lambda rng, rows: rows[:5] + ["1.0,zz,a,1"] + rows[5:],
    "blank line": lambda rng, rows: rows[:7] + [""] + rows[7:],
    "spaces line": lambda rng, rows: rows[:7] + ["   "] + rows[7:],
    "crlf": lambda rng, rows: [r + "\r" for r in rows],
    "quoted": lambda rng, rows: rows[:3] + ['"' + rows[3].replace(",", '",', 1)] + rows[4:],
    "extra field": lambda rng, rows: rows[:4] + [rows[4] + ",x"] + rows[5:],
    "short line": lambda rng, rows: rows[:4] + [rows[4].rsplit(",", 1)[0]] + rows[5:],
    "empty field": lambda rng, rows: rows[:4] + [",".join([""] + rows[4].split(",")[1:])] + rows[5:],
    "upper case": lambda rng, rows: [r.upper() if k % 17 == 3 else r for k, r in enumerate(rows)],
    "padded": lambda rng, rows: [r.replace(",", " , ") if k % 13 == 5 else r for k, r in enumerate(rows)],
    "nan": lambda rng, rows: rows[:6] + ["nan" + rows[6][rows[6].index(",") :]] + rows[7:],
    "lone stamp": lambda rng, rows: rows + ["1e11" + rows[-1][rows[-1].index(",") :]],
    "bad byte": lambda rng, rows: rows[:2] + [rows[2] + "\udcff"] + rows[3:],
    "iso": lambda rng, rows: rows[:2] + ["2024-05-01T10:00:00Z" + rows[2][rows[2].index(",") :]] + rows[3:],
}


def _write(path: Path, header, rows, *, final_newline=True) -> Path:
    text = "\n".join(header + rows) + ("\n" if final_newline else "")
    path.write_bytes(text.encode("utf-8", errors="surrogateescape"))
    return path


def _same_beams(path, epoch=None):
    fast = decode_beam_log(path, BEAMS, epoch=epoch)
    slow = decode_raw_beams(read_csv_rows(path, BEAM_COLUMNS), BEAMS, epoch=epoch, path=path)
    for name in ("events", "crossings", "aborted", "unfinished", "rejects"):
        a, b = getattr(fast, name), getattr(slow, name)
        assert a.schema == b.schema and a.equals(b), name
    return fast


def _same_toggles(path, epoch=None):
    rules = DebounceRules(chatter_window=0.4, min_on=0.2)
    fast = read_motion_csv(path, SENSORS, epoch=epoch, rules=rules)
    slow = read_motion(read_csv_rows(path, TOGGLE_COLUMNS), SENSORS, epoch=epoch, path=path, rules=rules)
    for name in ("motion", "rejects", "suppressed"):
        a, b = getattr(fast, name), getattr(slow, name)
        assert a.schema == b.schema and a.equals(b), name
    assert fast.reordered == slow.reordered
    return fast


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("n", [1, 50, 25_000])  # 25 000: the compiled kernels' side of MIN_ROWS
def test_clean_files_take_the_fast_path_with_the_same_result(tmp_path, seed, n):
    rng = np.random.default_rng(seed)
    header, rows = _beam_lines(rng, n)
    beams = _write(tmp_path / "beams.csv", header, rows, final_newline=seed % 2 == 0)
    assert clean_beam_events(beams, BEAMS) is not None
    out = _same_beams(beams)
    assert out.events.height + out.rejects.height == n
    header, rows = _toggle_lines(rng, n)
    toggles = _write(tmp_path / "motion.csv", header, rows)
    assert clean_toggle_rows(toggles, SENSORS) is not None
    _same_toggles(toggles)


@pytest.mark.parametrize("fault", sorted(FAULTS))
@pytest.mark.parametrize("seed", range(3))
def test_faulty_files_give_the_same_frames_and_rejects(tmp_path, fault, seed):
    rng = np.random.default_rng(100 + seed)
    header, rows = _beam_lines(rng, 60)
    beams = _write(tmp_path / "beams.csv", header, FAULTS[fault](rng, rows))
    _same_beams(beams)
    header, rows = _toggle_lines(rng, 60)
    toggles = _write(tmp_path / "motion.csv", header, FAULTS[fault](rng, rows))
    _same_toggles(toggles)


@pytest.mark.parametrize("fault", ["duplicate", "backwards", "slightly late"])
def test_ordering_faults_stay_on_the_fast_path(tmp_path, fault):
    """Duplicates and rows out of order are found by the fast path itself (its rejects equal
    the row-by-row path's, raw text included)."""
    rng = np.random.default_rng(7)
    header, rows = _toggle_lines(rng, 80)
    toggles = _write(tmp_path / "motion.csv", header, FAULTS[fault](rng, rows))
    typed = clean_toggle_rows(toggles, SENSORS)
    assert typed is not None
    out = _same_toggles(toggles)
    assert out.rejects.height + out.reordered >= 1
    assert out.rejects["raw"].null_count() == 0


@pytest.mark.parametrize(
    "fault",
    [
        "blank line",
        "crlf",
        "quoted",
        "extra field",
        "short line",
        "empty field",
        "upper case",
        "nan",
        "lone stamp",
        "bad byte",
        "iso",
        "spaces line",
    ],
)
def test_files_with_bad_or_unusual_lines_leave_the_fast_path(tmp_path, fault):
    rng = np.random.default_rng(3)
    header, rows = _beam_lines(rng, 200)
    beams = _write(tmp_path / "beams.csv", header, FAULTS[fault](rng, rows))
    assert clean_beam_events(beams, BEAMS) is None


def test_epochs_and_run_origins_match(tmp_path):
    rng = np.random.default_rng(5)
    header, rows = _toggle_lines(rng, 300)
    rows = [f"{1.7e9 + float(r.split(',', 1)[0])},{r.split(',', 1)[1]}" for r in rows]
    toggles = _write(tmp_path / "motion.csv", header, rows)
    _same_toggles(toggles)
    _same_toggles(toggles, epoch="2023-11-14T22:13:20Z")
    _same_toggles(toggles, epoch=TimeOrigin(origin=1.7e9, numeric=1.7e9, iso=1.7e9, lo=0.0, hi=50.0, source="data"))


def test_header_with_extra_columns_in_any_order(tmp_path):
    path = tmp_path / "beams.csv"
    path.write_text("note, blocked ,pair,beam,t\nx,1,a,a,0.5\ny,0,a,a,0.7\n")
    frame = read_clean_csv(path, {"t": pl.Float64, "beam": pl.Enum(list(BEAMS))})
    assert frame is not None and frame["line"].to_list() == [2, 3] and frame["t"].to_list() == [0.5, 0.7]
    _same_beams(path)
