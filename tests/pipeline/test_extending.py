"""docs/extending.md, followed: each of its guides done once, the way it says.

* **A tracker**: ``last-beam`` puts its one agent at the midpoint of the beam it last crossed.
  It is declared exactly as the guide says (a TrackerSpec with a frozen config, a scorer, a viz
  function, one TrackerEntry) and passed to the runner beside the built-in ones.
* **An input format**: an importer for a small foreign export (JSON lines of door contacts)
  writes the canonical files; ``onebit run`` reads them as any dataset.

The guides' own code (a tracker, a report metric, a sensor kind) is run as written by
``tests/docs/test_extending.py``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np
import polars as pl
import pytest

from onebit.core.errors import ConfigError
from onebit.core.params import param, validate
from onebit.core.site import Site, load_site
from onebit.core.tables import CROSSINGS, TRACKS, check_schema, conform
from onebit.core.writers import to_toml, write_csv, write_text
from onebit.datasets.beams_sim import write_beams_dataset
from onebit.datasets.importers import graph_site_toml
from onebit.pipeline.config_show import show
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline
from onebit.pipeline.stages import TRACKERS, TrackerEntry, stages
from onebit.scoring.mot import Gate
from onebit.trackers.base import TrackerSpec
from onebit.viz.families import GENERIC, Look
from onebit.viz.inspect import entity_paths
from onebit.viz.tracks import log_point_tracks

NAME = "last-beam"


@dataclass(frozen=True, kw_only=True)
class LastBeamConfig:
    """``[last-beam]``: a time offset added to every estimate (s)."""

    delay: float = param(0.0, "time offset added to every estimate", lo=0.0, unit="s")

    def __post_init__(self) -> None:
        validate(self)


def run(inputs: dict, site: Site, config: LastBeamConfig) -> dict[str, pl.DataFrame]:
    crossings = check_schema(inputs["crossings"], CROSSINGS, name="crossings").sort("t")
    mid = {b.id: np.mean([b.p0, b.p1], axis=0) for b in site.beams}
    xy = np.array([mid[b] for b in crossings["beam"]]).reshape(-1, 2)
    tracks = pl.DataFrame(
        {"tracker": NAME, "track": "agent", "t": crossings["t"] + config.delay, "x": xy[:, 0], "y": xy[:, 1]},
        schema_overrides={"tracker": pl.String, "track": pl.String},
    )
    return {"tracks": conform(tracks, TRACKS)}


def score(tracker: str, tables: dict, site: Site, region_graph) -> tuple[list, dict]:
    tracks = tables[f"{tracker}_tracks"]
    return [(tracker, "estimates", float(tracks.height), "estimates")], {}


def log_run(rec, tracker, out, *, site, region_graph, config, tables, look=GENERIC) -> None:
    log_point_tracks(rec, tracker, out["tracks"], rgb=look.rgb)


GATE = Gate("point", 0.5, "m", "an agent within half a metre of the true one is a hit")
ENTRY = TrackerEntry(
    TrackerSpec(name=NAME, needs=("crossings",), config=LastBeamConfig, run=run),
    score,
    log_run,
    gate=GATE,
    look=Look(rgb=(10, 250, 10)),  # no family: the generic layout, in its own colour
)


def _colors(rrd, entity: str) -> set[int]:
    """Every packed RGBA colour logged on ``entity`` (Points2D / LineStrips2D colours)."""
    from rerun.chunk import RrdReader

    out: set[int] = set()
    for chunk in RrdReader(str(rrd)).stream():
        if str(chunk.entity_path) != entity:
            continue
        frame = pl.from_arrow(chunk.to_record_batch())
        for col in frame.columns:
            if col.endswith(":colors"):
                out |= {int(v) for v in frame[col].explode().drop_nulls().to_list()}
    return out


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    return write_beams_dataset(tmp_path_factory.mktemp("ext") / "d", "beams-lab", seed=1, duration=40.0, camera=False)


def test_a_dummy_tracker_runs_end_to_end(data, tmp_path):
    res = run_pipeline(data, tmp_path / "run", trackers=("beams", NAME), tracker_entries=(*TRACKERS, ENTRY))
    assert res.status[NAME].startswith("ok"), res.status
    tracks = pl.read_parquet(tmp_path / "run" / "tables" / f"{NAME}_tracks.parquet")
    crossings = pl.read_parquet(tmp_path / "run" / "tables" / "crossings.parquet")
    assert tracks.schema == TRACKS and tracks.height == crossings.height > 0
    assert metric(res.report, f"{NAME}/estimates") == tracks.height
    # the standard MOT metrics come for free with a gate; the lab is in feet: 0.5 m = 1.64 ft
    assert 0.0 <= metric(res.report, f"{NAME}/hota") <= 1.0 and metric(res.report, f"{NAME}/mota") <= 1.0
    assert metric(res.report, f"{NAME}/mot_gate") == pytest.approx(0.5 / 0.3048)
    assert f"{NAME}/tracks/agent" in entity_paths(tmp_path / "run" / "rrd" / f"{NAME}.rrd")
    # drawn in the colour its entry declares (one track: the colour itself, RGBA packed)
    assert 0x0AFA0AFF in _colors(tmp_path / "run" / "rrd" / f"{NAME}.rrd", f"/{NAME}/tracks/agent")
    # the beams tracker still reads the corrected crossings; the dummy reads the decoded ones
    assert res.status["beams"].startswith("ok")


def test_its_config_section_is_validated_and_recorded(data, tmp_path):
    res = run_pipeline(
        data, tmp_path / "a", trackers=(NAME,), tracker_entries=(*TRACKERS, ENTRY), config={NAME: {"delay": 2.0}}
    )
    assert res.ok, res.status
    tracks = pl.read_parquet(tmp_path / "a" / "tables" / f"{NAME}_tracks.parquet")
    crossings = pl.read_parquet(tmp_path / "a" / "tables" / "crossings.parquet")
    assert np.allclose(tracks["t"].to_numpy(), crossings.sort("t")["t"].to_numpy() + 2.0)
    assert "delay = 2.0" in (tmp_path / "a" / "run.toml").read_text()
    # refused when the run starts (nothing written), naming the section and the field
    with pytest.raises(ConfigError, match=rf"\[{NAME}\] unknown field 'dealy'"):
        run_pipeline(
            data, tmp_path / "b", trackers=(NAME,), tracker_entries=(*TRACKERS, ENTRY), config={NAME: {"dealy": 1}}
        )
    assert not (tmp_path / "b" / "run.toml").exists()
    # its declared parameter is listed by `onebit config show` and probed like every other
    shown = show(NAME, stage_list=stages((*TRACKERS, ENTRY)))
    assert "# time offset added to every estimate.\n# (float, s, >= 0.0)\ndelay = 0.0\n" in shown
    with pytest.raises(ConfigError, match=r"LastBeamConfig\.delay = -1\.0; allowed range"):
        LastBeamConfig(delay=-1.0)


def test_unknown_tracker_names_the_known_ones(data, tmp_path):
    with pytest.raises(ConfigError, match=NAME):
        run_pipeline(data, tmp_path / "c", trackers=("nope",), tracker_entries=(*TRACKERS, ENTRY))


# --------------------------------------------------------------------------- an input format (an importer)

DOORS = {"front": (0.0, 2.0), "hall": (3.0, 2.0), "kitchen": (6.0, 2.0)}


def import_doorlog(file, dataset) -> dict:
    """A JSON-lines export of door contacts (``{"ts_ms": ..., "door": ..., "open": true}``) ->
    ``site.toml`` (the doors in a row, each next to the next), ``motion.csv``, ``rejects.csv``
    and ``import.toml``. Lines it cannot read are kept with their line number and reason."""
    rows, rejects = [], []
    for line_no, text in enumerate(open(file, encoding="utf-8"), start=1):
        try:
            rec = json.loads(text)
            rows.append((rec["ts_ms"] / 1000.0, str(rec["door"]), 1 if rec["open"] else 0))
        except (ValueError, KeyError, TypeError) as exc:
            rejects.append(
                (str(file), line_no, "line", f"not a door record: {type(exc).__name__}: {exc}", text.strip())
            )
    ids = list(DOORS)
    site = graph_site_toml(
        name="doorlog", units="m", positions=DOORS, edges=list(zip(ids, ids[1:])), doors=["front"], sensor_range=1.0
    )
    write_text(site, dataset / "site.toml")
    write_csv(pl.DataFrame(rows, schema=["t", "sensor", "value"], orient="row"), dataset / "motion.csv")
    write_csv(
        pl.DataFrame(rejects, schema=["file", "line", "field", "reason", "raw"], orient="row"), dataset / "rejects.csv"
    )
    counts = {"lines": len(rows) + len(rejects), "events": len(rows), "rejected": len(rejects)}
    write_text(to_toml({"source": {"file": str(file), "format": "doorlog"}, "counts": counts}), dataset / "import.toml")
    return counts


def test_an_importer_writes_a_dataset_any_run_reads(tmp_path):
    export = tmp_path / "doors.jsonl"
    walk = [
        (0, "front", True),
        (1500, "front", False),
        (2500, "hall", True),
        (4000, "hall", False),
        (5000, "kitchen", True),
        (6500, "kitchen", False),
    ]
    lines = [json.dumps({"ts_ms": t, "door": d, "open": o}) for t, d, o in walk]
    export.write_text("\n".join(lines[:3] + ["{broken"] + lines[3:]) + "\n")
    (tmp_path / "d").mkdir()
    counts = import_doorlog(export, tmp_path / "d")
    assert counts == {"lines": 7, "events": 6, "rejected": 1}
    assert load_site(tmp_path / "d" / "site.toml").sensor_graph is not None
    res = run_pipeline(tmp_path / "d", tmp_path / "run", trackers=("hmm1",))
    assert res.ok, res.status
    assert metric(res.report, "motion/edges") == 6.0
    tracks = pl.read_parquet(tmp_path / "run" / "tables" / "hmm1_tracks.parquet")
    assert tracks.height > 0 and set(tracks["node"].drop_nulls()) <= set(DOORS)
    rejected = pl.read_csv(tmp_path / "d" / "rejects.csv")
    assert rejected["line"].to_list() == [4]
