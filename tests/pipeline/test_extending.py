"""docs/extending.md, followed: a small dummy tracker added to the stage list runs end to end.

The tracker ``last-beam`` puts its one agent at the midpoint of the beam it last crossed.
It is declared exactly as docs/extending.md says (a TrackerSpec with a frozen config, a
scorer, a viz function, one TrackerEntry) and passed to the runner beside the built-in ones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl
import pytest

from onebit.core.config import check_range
from onebit.core.errors import ConfigError
from onebit.core.site import Site
from onebit.core.tables import CROSSINGS, TRACKS, check_schema, conform
from onebit.datasets.beams_sim import write_beams_dataset
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline
from onebit.pipeline.stages import TRACKERS, TrackerEntry
from onebit.scoring.mot import Gate
from onebit.trackers.base import TrackerSpec
from onebit.viz.inspect import entity_paths
from onebit.viz.tracks import log_point_tracks

NAME = "last-beam"


@dataclass(frozen=True, kw_only=True)
class LastBeamConfig:
    """``[last-beam]``: a time offset added to every estimate (s)."""

    delay: float = 0.0

    def __post_init__(self) -> None:
        check_range(self, "delay", 0.0, None)


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


def log_run(rec, tracker, out, *, site, region_graph, config, tables) -> None:
    log_point_tracks(rec, tracker, out["tracks"])


GATE = Gate("point", 0.5, "m", "an agent within half a metre of the true one is a hit")
ENTRY = TrackerEntry(TrackerSpec(name=NAME, needs=("crossings",), config=LastBeamConfig, run=run), score, log_run, gate=GATE)


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
    # the beams tracker still reads the corrected crossings; the dummy reads the decoded ones
    assert res.status["beams"].startswith("ok")


def test_its_config_section_is_validated_and_recorded(data, tmp_path):
    res = run_pipeline(data, tmp_path / "a", trackers=(NAME,), tracker_entries=(*TRACKERS, ENTRY), config={NAME: {"delay": 2.0}})
    assert res.ok, res.status
    tracks = pl.read_parquet(tmp_path / "a" / "tables" / f"{NAME}_tracks.parquet")
    crossings = pl.read_parquet(tmp_path / "a" / "tables" / "crossings.parquet")
    assert np.allclose(tracks["t"].to_numpy(), crossings.sort("t")["t"].to_numpy() + 2.0)
    assert "delay = 2.0" in (tmp_path / "a" / "run.toml").read_text()
    # refused when the run starts (nothing written), naming the section and the field
    with pytest.raises(ConfigError, match=rf"\[{NAME}\] unknown field 'dealy'"):
        run_pipeline(data, tmp_path / "b", trackers=(NAME,), tracker_entries=(*TRACKERS, ENTRY), config={NAME: {"dealy": 1}})
    assert not (tmp_path / "b" / "run.toml").exists()


def test_unknown_tracker_names_the_known_ones(data, tmp_path):
    with pytest.raises(ConfigError, match=NAME):
        run_pipeline(data, tmp_path / "c", trackers=("nope",), tracker_entries=(*TRACKERS, ENTRY))
