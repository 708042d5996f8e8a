"""docs/extending.md's raw-file guide, run as it is written: its code blocks (the reader
module, the stage's work, its declaration) become a module at the path it names, a stage's
work beside the other reader stages and one entry of the stage list; the stem goes in
``TIME_SOURCES``. A run then reads the new log from a CSV file, on the run's one time origin,
with every bad line a reject; the reader takes an MCAP channel's rows too. A guide that stops
working fails here."""

from __future__ import annotations

import re
import sys
import tomllib
import types
from pathlib import Path

import polars as pl
import pytest

from onebit.core.tables import REJECTS
from onebit.core.writers import write_csv, write_text
from onebit.datasets.importers import graph_site_toml
from onebit.pipeline import reading, runner
from onebit.pipeline import stages as stage_list
from onebit.pipeline.context import Stage
from onebit.pipeline.report import metric
from onebit.pipeline.stages import TRACKERS
from onebit.readers.rows import RawRows

ROOT = Path(__file__).resolve().parents[2]
GUIDE = ROOT / "docs" / "extending.md"
BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)
T0 = 1_700_000_000.0  # the door log's first stamp: Unix seconds, as a deployment writes them


def guide_blocks() -> list[str]:
    """The python blocks of the raw-file guide: from its reader section to the next guide."""
    text = GUIDE.read_text()
    start = text.index("## 1. The reader: `onebit/readers/<format>.py`")
    end = text.index("# Adding a sensor kind", start)
    return BLOCK.findall(text[start:end])


@pytest.fixture
def doors_stage(monkeypatch) -> Stage:
    """The guide followed: the reader installed as ``onebit.readers.doors``, the stage's work
    made in ``onebit.pipeline.reading``'s namespace, its declaration in the stage list after
    ``proximity`` and its stem in ``TIME_SOURCES``."""
    reader, work, declaration = guide_blocks()
    module = types.ModuleType("onebit.readers.doors")
    module.__file__ = "onebit/readers/doors.py"
    exec(compile(reader, "docs/extending.md (onebit/readers/doors.py)", "exec"), module.__dict__)
    monkeypatch.setitem(sys.modules, "onebit.readers.doors", module)
    ns = dict(vars(reading))
    exec(compile(work, "docs/extending.md (onebit/pipeline/reading.py)", "exec"), ns)
    (entry,) = [line for line in declaration.splitlines() if line and not line.startswith("#")]
    stage = eval(entry.rstrip(","), {"Stage": Stage, "reading": types.SimpleNamespace(**ns)})
    declared = stage_list.stages

    def with_doors(trackers=TRACKERS):
        out = declared(trackers)
        i = [s.name for s in out].index("proximity") + 1
        return [*out[:i], stage, *out[i:]]

    monkeypatch.setattr(stage_list, "stages", with_doors)
    monkeypatch.setattr(reading, "TIME_SOURCES", (*reading.TIME_SOURCES, "doors"))
    return stage


def test_the_guide_has_a_reader_a_stage_and_its_declaration():
    reader, work, declaration = guide_blocks()
    assert reader.startswith("# onebit/readers/doors.py\n") and "def read_doors(log: Log" in reader
    assert work.startswith("# onebit/pipeline/reading.py") and "def doors_work(ctx" in work
    assert declaration.startswith("# onebit/pipeline/stages.py:") and 'Stage("doors"' in declaration


def _dataset(d: Path) -> None:
    d.mkdir()
    doors = {"front": (0.0, 2.0), "hall": (3.0, 2.0), "kitchen": (6.0, 2.0)}
    ids = list(doors)
    site = graph_site_toml(
        name="doors", units="m", positions=doors, edges=list(zip(ids, ids[1:])), doors=["front"], sensor_range=1.0
    )
    write_text(site, d / "site.toml")
    # the motion log starts 10 s after the door log: the door log sets t = 0
    motion = [(T0 + 10.0, "front", 1), (T0 + 11.5, "front", 0), (T0 + 12.5, "hall", 1), (T0 + 14.0, "hall", 0)]
    write_csv(pl.DataFrame(motion, schema=["t", "sensor", "value"], orient="row"), d / "motion.csv")
    (d / "doors.csv").write_text(
        "t,door,state\n"
        f"{T0:.1f},front,open\n"
        f"{T0 + 2:.1f},front,closed\n"
        f"{T0 + 3:.1f},front,ajar\n"  # line 4: not a state
        "soon,hall,open\n"  # line 5: not a time
        f"{T0 + 9:.1f},hall,open\n"
    )


def test_a_run_reads_the_new_log_on_the_runs_time_origin(doors_stage, tmp_path):
    _dataset(tmp_path / "d")
    res = runner.run_pipeline(tmp_path / "d", tmp_path / "run", trackers=("hmm1",))
    assert res.status["doors"].startswith("ok"), res.status
    assert res.ok, res.status
    events = pl.read_parquet(tmp_path / "run" / "tables" / "door_events.parquet")
    assert events.to_dicts() == [
        {"t": 0.0, "door": "front", "open": True},
        {"t": 2.0, "door": "front", "open": False},
        {"t": 9.0, "door": "hall", "open": True},
    ]
    assert metric(res.report, "doors/events") == 3.0
    # one clock for every log: the door log's start is t = 0 for the motion log too
    time = tomllib.loads((tmp_path / "run" / "run.toml").read_text())["time"]
    assert time["origin_s"] == T0
    motion = pl.read_parquet(tmp_path / "run" / "tables" / "motion.parquet")
    assert motion["t"].min() == 10.0
    rejects = pl.read_parquet(tmp_path / "run" / "tables" / "rejects.parquet").filter(pl.col("source") == "doors.csv")
    assert rejects["line"].to_list() == [4, 5]
    assert "'ajar' is not one of open|closed" in rejects["reason"][0]
    assert rejects["raw"].to_list() == [f"{T0 + 3:.1f},front,ajar", "soon,hall,open"]


def test_the_reader_takes_an_mcap_channels_rows_as_it_takes_the_file(doors_stage, tmp_path):
    """The same rows as a channel's (String columns, ``line`` the message's index, ``raw`` its
    text) give the same table and the same reasons, named by the channel."""
    read_doors = sys.modules["onebit.readers.doors"].read_doors
    _dataset(tmp_path / "d")
    lines = (tmp_path / "d" / "doors.csv").read_text().splitlines()[1:]
    frame = pl.DataFrame(
        {
            "t": [x.split(",")[0] for x in lines],
            "door": [x.split(",")[1] for x in lines],
            "state": [x.split(",")[2] for x in lines],
            "line": list(range(1, len(lines) + 1)),
            "raw": lines,
        },
        schema_overrides={"line": pl.Int64},
    )
    raw = RawRows("rec.mcap:/doors", frame, pl.DataFrame(schema=REJECTS))
    from_rows, rejected = read_doors(raw)  # no run, no origin: the stamps as written
    from_file, file_rejected = read_doors(tmp_path / "d" / "doors.csv")
    assert from_rows.equals(from_file) and from_rows["t"].to_list() == [T0, T0 + 2, T0 + 9]
    assert rejected["source"].unique().to_list() == ["rec.mcap:/doors"]
    assert rejected["reason"].to_list() == file_rejected["reason"].to_list()
