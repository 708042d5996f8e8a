"""MCAP raw logs: CSV <-> MCAP round trips, truncation, bad input, and ``logs info``."""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

import polars as pl
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.records import Message
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from onebit.core.errors import InputError
from onebit.core.tables import REJECTS
from onebit.readers.loginfo import LOG_INFO, format_log_info, log_info
from onebit.readers.mcap_io import (
    CHANNELS,
    csv_folder_to_mcap,
    mcap_to_csv_folder,
    read_mcap,
    write_mcap,
)

BEAMS_CSV = """t,beam,pair,blocked
0.5,b1,a,1
0.7,b1,b,1
1.0,b1,a,0
1.25,b2,a,1
2.0,b3,b,1
2.5,b2,a,0
"""


def _folder(tmp: Path) -> Path:
    tmp.mkdir(parents=True, exist_ok=True)
    (tmp / "beams.csv").write_text(BEAMS_CSV)
    (tmp / "motion.csv").write_text("t,sensor,value\n0.1,m1,1\n0.9,m2,1\n1.9,m1,0\n")
    (tmp / "truth.csv").write_text("t,target,x,y\n0.0,p1,1.5,-2\n1.0,p1,1.75,-2.25\n")
    return tmp


def _read_all_csv(folder: Path) -> dict[str, pl.DataFrame]:
    return {p.stem: pl.read_csv(p, infer_schema=False) for p in sorted(folder.glob("*.csv"))}


# --------------------------------------------------------------------------- round trips


def test_folder_round_trip(tmp_path):
    src = _folder(tmp_path / "in")
    out = tmp_path / "rec.mcap"
    conv = csv_folder_to_mcap(src, out)
    assert conv.written == [out]
    back = mcap_to_csv_folder(out, tmp_path / "out")
    assert back.rejects.height == 0
    assert {p.name for p in back.written} == {"beams.csv", "motion.csv", "truth.csv"}
    before, after = _read_all_csv(src), _read_all_csv(tmp_path / "out")
    assert before.keys() == after.keys()
    for stem in before:
        assert before[stem].equals(after[stem]), stem
    # nothing but the outputs is left behind (atomic writes clean their temp files)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in", "out", "rec.mcap"]
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["beams.csv", "motion.csv", "truth.csv"]


def test_read_mcap_shape_and_log_times(tmp_path):
    out = tmp_path / "rec.mcap"
    csv_folder_to_mcap(_folder(tmp_path), out)
    contents = read_mcap(out)
    assert not contents.truncated
    assert contents.rejects.schema == REJECTS and contents.rejects.height == 0
    beams = contents.channels["/beams"]
    assert beams.schema == pl.Schema(
        {"t": pl.String, "beam": pl.String, "pair": pl.String, "blocked": pl.String, "line": pl.Int64, "raw": pl.String}
    )
    assert beams["line"].to_list() == list(range(1, 7))
    assert json.loads(beams["raw"][0]) == {"t": "0.5", "beam": "b1", "pair": "a", "blocked": "1"}
    # messages are in time order across channels, log_time = publish_time = round(t * 1e9)
    with open(out, "rb") as fh:
        msgs = [r for r in StreamReader(fh).records if isinstance(r, Message)]
    times = [m.log_time for m in msgs]
    assert times == sorted(times)
    assert all(m.publish_time == m.log_time for m in msgs)
    assert 1_250_000_000 in times


def test_parquet_input(tmp_path):
    pl.read_csv(BEAMS_CSV.encode()).write_parquet(tmp_path / "beams.parquet")
    csv_folder_to_mcap(tmp_path / "beams.parquet", tmp_path / "b.mcap")
    beams = read_mcap(tmp_path / "b.mcap").channels["/beams"]
    assert beams["beam"].to_list() == ["b1", "b1", "b1", "b2", "b3", "b2"]
    assert [float(v) for v in beams["t"]] == [0.5, 0.7, 1.0, 1.25, 2.0, 2.5]


_text = st.text(alphabet=st.characters(codec="utf-8", exclude_categories=("Cs", "Cc")), max_size=6)
_floats = st.floats(allow_nan=False, allow_infinity=False, width=64)


@settings(max_examples=40, deadline=None)
@given(
    rows=st.lists(st.tuples(_floats, _text, st.sampled_from(["a", "b"]), st.sampled_from(["0", "1", ""])), max_size=25)
)
def test_csv_round_trip_property(rows):
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "in").mkdir()
        df = pl.DataFrame(
            [(repr(t), beam, pair, blocked) for t, beam, pair, blocked in rows],
            schema={c: pl.String for c in CHANNELS["/beams"]},
            orient="row",
        )
        df.write_csv(tmp / "in" / "beams.csv")
        csv_folder_to_mcap(tmp / "in", tmp / "r.mcap")
        mcap_to_csv_folder(tmp / "r.mcap", tmp / "out")
        before = pl.read_csv(tmp / "in" / "beams.csv", infer_schema=False)
        after = pl.read_csv(tmp / "out" / "beams.csv", infer_schema=False)
        assert before.equals(after)


@settings(max_examples=40, deadline=None)
@given(rows=st.lists(st.tuples(_floats, _text, _floats, _floats), max_size=25))
def test_typed_table_round_trip_property(rows):
    df = pl.DataFrame(
        rows, schema={"t": pl.Float64, "target": pl.String, "x": pl.Float64, "y": pl.Float64}, orient="row"
    )
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "t.mcap"
        write_mcap(path, {"/truth": df})
        got = read_mcap(path).channels["/truth"]
    assert got["line"].to_list() == list(range(1, df.height + 1))
    typed = got.select(
        pl.col("t").cast(pl.Float64), pl.col("target"), pl.col("x").cast(pl.Float64), pl.col("y").cast(pl.Float64)
    )
    assert typed.equals(df)


def test_write_rejects_unknown_topic_and_bad_columns(tmp_path):
    with pytest.raises(InputError, match="unknown topic"):
        write_mcap(tmp_path / "x.mcap", {"/nope": pl.DataFrame({"t": [1.0]})})
    with pytest.raises(InputError, match="missing"):
        write_mcap(tmp_path / "x.mcap", {"/motion": pl.DataFrame({"t": [1.0], "sensor": ["m"]})})
    assert not list(tmp_path.iterdir())


# --------------------------------------------------------------------------- truncation


def _message_ends(path: Path) -> list[tuple[str, int]]:
    """(topic, byte offset where the message record ends) for every message, in file order."""
    topics = {}
    out = []
    with open(path, "rb") as fh:
        for rec in StreamReader(fh).records:
            if type(rec).__name__ == "Channel":
                topics[rec.id] = rec.topic
            elif isinstance(rec, Message):
                out.append((topics[rec.channel_id], fh.tell()))
    return out


def test_truncated_file_keeps_complete_messages(tmp_path):
    full = tmp_path / "full.mcap"
    csv_folder_to_mcap(_folder(tmp_path / "in"), full)
    data = full.read_bytes()
    ends = _message_ends(full)
    complete = read_mcap(full).channels
    cuts = sorted(
        {
            9,
            40,
            ends[0][1] - 1,
            ends[0][1],
            ends[3][1] + 5,
            ends[-1][1] - 3,
            ends[-1][1],
            ends[-1][1] + 20,
            len(data) - 4,
            len(data) - 1,
        }
    )
    for cut in cuts:
        part = tmp_path / f"cut{cut}.mcap"
        part.write_bytes(data[:cut])
        got = read_mcap(part)
        kept = [topic for topic, end in ends if end <= cut]
        assert got.truncated, cut
        for topic in CHANNELS:
            n = kept.count(topic)
            frame = got.channels.get(topic)
            if frame is None:
                assert n == 0, (cut, topic)
                continue
            assert frame.equals(complete[topic].head(n)), (cut, topic)
        assert got.rejects.height == 1, cut
        rej = got.rejects.row(0, named=True)
        assert rej["source"] == part.name
        assert "truncated" in rej["reason"] and "byte" in rej["reason"]
        assert rej["line"] == len(kept) + 1


def test_not_mcap_raises_naming_file(tmp_path):
    bad = tmp_path / "fake.mcap"
    bad.write_text("t,beam,pair,blocked\n1,b1,a,1\n")
    with pytest.raises(InputError, match="fake.mcap") as info:
        read_mcap(bad)
    assert "not an MCAP" in str(info.value)
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    with pytest.raises(InputError, match="empty.mcap"):
        read_mcap(empty)
    with pytest.raises(InputError, match="missing.mcap"):
        read_mcap(tmp_path / "missing.mcap")


# --------------------------------------------------------------------------- bad messages


def _hand_made(path: Path, *, chunked: bool = True) -> None:
    with open(path, "wb") as fh:
        w = Writer(fh, compression=CompressionType.ZSTD, use_chunking=chunked)
        w.start()
        sid = w.register_schema("beams", "jsonschema", b"{}")
        beams = w.register_channel("/beams", "json", sid)
        other = w.register_channel("/weather", "json", 0)
        msgs = [
            (beams, b'{"t": 0.5, "beam": "b1", "pair": "a", "blocked": 1}'),
            (beams, b'{"t": 0.6, "beam": "b1", '),
            (beams, b"[1, 2]"),
            (other, b'{"t": 0.7}'),
            (beams, b'{"t": 0.8, "beam": "b1", "pair": "b"}'),
            (beams, b'{"t": "0.9", "beam": null, "pair": "b", "blocked": true}'),
        ]
        for i, (ch, data) in enumerate(msgs):
            w.add_message(ch, log_time=i, data=data, publish_time=i)
        w.finish()


def test_bad_messages_go_to_rejects(tmp_path):
    path = tmp_path / "hand.mcap"
    _hand_made(path)
    got = read_mcap(path)
    assert not got.truncated
    beams = got.channels["/beams"]
    assert beams["line"].to_list() == [1, 5]
    assert beams.row(0) == ("0.5", "b1", "a", "1", 1, '{"t": 0.5, "beam": "b1", "pair": "a", "blocked": 1}')
    assert beams.row(1)[:4] == ("0.9", None, "b", "true")
    rej = got.rejects.sort("source", "line")
    assert rej.select("source", "line").rows() == [
        ("hand.mcap:/beams", 2),
        ("hand.mcap:/beams", 3),
        ("hand.mcap:/beams", 4),
        ("hand.mcap:/weather", 1),
    ]
    reasons = rej["reason"].to_list()
    assert "not valid JSON" in reasons[0]
    assert "not a JSON object" in reasons[1]
    assert "missing field(s) 'blocked'" in reasons[2]
    assert "unknown topic /weather" in reasons[3]
    assert rej["raw"][0] == '{"t": 0.6, "beam": "b1", '


# --------------------------------------------------------------------------- logs info


def test_log_info_csv_and_mcap(tmp_path):
    (tmp_path / "beams.csv").write_text(BEAMS_CSV)
    info = log_info(tmp_path / "beams.csv")
    assert info.schema == LOG_INFO
    row = info.row(0, named=True)
    assert row["source"] == "beams.csv"
    assert row["rows"] == 6 and row["rejects"] == 0
    assert row["sensors"] == 3 and row["sensor_ids"] == "b1,b2,b3"
    assert row["t_min"] == 0.5 and row["t_max"] == 2.5 and row["span_s"] == 2.0
    assert math.isclose(row["rate_hz"], 3.0)

    csv_folder_to_mcap(tmp_path / "beams.csv", tmp_path / "rec.mcap")
    mrow = log_info(tmp_path / "rec.mcap").row(0, named=True)
    assert mrow == {**row, "source": "rec.mcap:/beams"}

    text = format_log_info(log_info(tmp_path))
    assert "beams.csv" in text and "rec.mcap:/beams" in text and "b1,b2,b3" in text


def test_log_info_counts_malformed_rows(tmp_path):
    bad = BEAMS_CSV + "oops,b1,a,1\n3.0,b1,a,1,extra\n3.5,b4\n"
    (tmp_path / "beams.csv").write_text(bad)
    row = log_info(tmp_path / "beams.csv").row(0, named=True)
    assert row["rows"] == 6 and row["rejects"] == 3
    assert row["sensors"] == 3 and row["t_max"] == 2.5


def test_log_info_mcap_rejects_and_truncation(tmp_path):
    path = tmp_path / "hand.mcap"
    _hand_made(path)
    info = {r["source"]: r for r in log_info(path).iter_rows(named=True)}
    assert info["hand.mcap:/beams"]["rows"] == 2 and info["hand.mcap:/beams"]["rejects"] == 3
    assert info["hand.mcap:/weather"]["rows"] == 0 and info["hand.mcap:/weather"]["rejects"] == 1

    _hand_made(path, chunked=False)
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: _message_ends(path)[0][1] + 3])
    info = {r["source"]: r for r in log_info(cut).iter_rows(named=True)}
    assert info["cut.mcap:/beams"]["rows"] == 1
    assert info["cut.mcap"]["rejects"] == 1


def test_log_info_many_sensors_truncates_ids(tmp_path):
    lines = ["t,sensor,value"] + [f"{i},s{i:02d},1" for i in range(15)]
    (tmp_path / "motion.csv").write_text("\n".join(lines) + "\n")
    row = log_info(tmp_path / "motion.csv").row(0, named=True)
    assert row["sensors"] == 15
    assert row["sensor_ids"].startswith("s00,s01") and row["sensor_ids"].endswith("(+5)")


def test_a_file_cut_in_its_header_is_unreadable_not_empty(tmp_path):
    full = tmp_path / "full.mcap"
    csv_folder_to_mcap(_folder(tmp_path / "in"), full)
    data = full.read_bytes()
    for cut in (4, 8, 12):
        part = tmp_path / f"cut{cut}.mcap"
        part.write_bytes(data[:cut])
        got = read_mcap(part)
        assert got.truncated and got.unreadable and not got.channels, cut
        assert got.rejects.rows() == [(part.name, 1, got.rejects["reason"][0], None)] and got.rejects["reason"][
            0
        ].startswith("unreadable: truncated in its MCAP header")
    assert not read_mcap(full).unreadable
