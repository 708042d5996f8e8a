"""The empty room (issue 12, item 1), on every tracker of the stage list.

Each tracker gets a log of its kind with a stretch in the middle where nobody is present
(every sensor off, nothing happening, far longer than ``absent_after``) and instants with no
detection at all. It must run (no exception), give TRACKS, report tracks where people are
and no track inside the empty stretch. CLUSTERTRACK also gets instants with every
proximity sensor off on a fully covered line (its feasible space is empty: nowhere).
"""

from __future__ import annotations

from pathlib import Path

import polars as pl
import pytest

from onebit.core.region_graph import build_region_graph
from onebit.core.site import load_site
from onebit.core.tables import TRACKS
from onebit.datasets.catalogue import get_scenario
from onebit.pipeline.stages import TRACKERS
from onebit.readers.beams import decode_beam_log
from onebit.readers.motion import MotionConfig, read_motion_csv, site_rules
from onebit.readers.proximity import proximity_frames, read_proximity_csv

ENTRIES = {e.name: e for e in TRACKERS}
GAP = 400.0  # seconds of empty room inserted in the middle of each log
KIND = {
    "beams": "beams-lab",
    "intruder": "pir14",
    "intruder-naive": "pir14",
    "clustertrack": "proximity-line",
    "findinghumo": "hallway",
    "hmm1": "hallway",
    "hmm2": "hallway",
    "findinghumo-flow": "hallway",
    "istate": "istate-room",
}


def _twice(df: pl.DataFrame, shift: float) -> pl.DataFrame:
    """The log, then the same log again ``shift`` seconds later: an empty stretch between."""
    return pl.concat([df, df.with_columns(pl.col("t") + shift)])


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> dict[str, tuple]:
    """Per kind: (site, inputs with an empty stretch, (start, end) of the stretch)."""
    root = tmp_path_factory.mktemp("empty-room")
    out = {}
    for kind, duration in (
        ("beams-lab", 40.0),
        ("pir14", 40.0),
        ("proximity-line", None),
        ("hallway", 40.0),
        ("istate-room", 30.0),
    ):
        d = get_scenario(kind).write(
            root / kind, seed=5, duration=duration, agents=None, drop=0.0, camera=False, params={}
        )
        site = load_site(Path(d) / "site.toml")
        inputs: dict = {"region_graph": build_region_graph(site)}
        if kind == "beams-lab":
            cr = decode_beam_log(Path(d) / "beams.csv", site.beam_ids).crossings
            end = float(cr["t"].max())
            inputs["crossings"] = _twice(cr, end + GAP)
        elif kind == "proximity-line":
            ids = [p.id for p in site.proximity_sensors]
            prox = read_proximity_csv(Path(d) / "proximity.csv", ids).motion
            frames = proximity_frames(prox, ids, period=1.0)
            end = float(frames["t"].max())
            # every sensor off for a stretch: the line is fully covered, so F is empty there
            off = frames.with_columns(t=pl.col("t") + end + 1.0, slot=pl.col("slot") + int(end) + 1, on=pl.lit(False))
            again = frames.with_columns(t=pl.col("t") + 2 * (end + 1.0), slot=pl.col("slot") + 2 * (int(end) + 1))
            inputs["proximity_frames"] = pl.concat([frames, off, again])
            out[kind] = (site, inputs, (end + 0.5, 2 * (end + 1.0) - 0.5))
            continue
        else:
            ids = [m.id for m in site.motion_sensors]
            mo = read_motion_csv(Path(d) / "motion.csv", ids, rules=site_rules(site, MotionConfig())).motion
            end = float(mo["t"].max())
            inputs["motion"] = _twice(mo, end + GAP)
        out[kind] = (site, inputs, (end + 1.0, end + GAP - 1.0))
    return out


@pytest.mark.parametrize("name", sorted(KIND))
def test_no_track_where_nobody_is(data, name):
    entry = ENTRIES[name]
    site, inputs, (a, b) = data[KIND[name]]
    out = entry.spec.run(
        {k: v for k, v in inputs.items() if k in (*entry.spec.needs, *entry.spec.wants, "region_graph")},
        site,
        entry.spec.config(),
    )
    tracks = out["tracks"]
    assert tracks.schema == TRACKS
    assert tracks.filter(pl.col("t") < a).height > 0, "tracks while people are there"
    assert tracks.filter(pl.col("t") > b).height > 0, "tracks once people are back"
    inside = tracks.filter(pl.col("t").is_between(a + 1e-9, b - 1e-9) & pl.col("x").is_not_null())
    if name == "beams":  # region tracks: a row per crossing, none while nobody crosses
        inside = tracks.filter(pl.col("t").is_between(a + 1e-9, b - 1e-9))
    assert inside.height == 0, inside.head()


def test_clustertrack_instants_with_every_sensor_off(data):
    """The crash of issue 12: F empty at an instant (every proximity sensor off) -- no reshape
    error, no track at those instants, tracks before and after."""
    site, inputs, (a, b) = data["proximity-line"]
    entry = ENTRIES["clustertrack"]
    out = entry.spec.run(inputs, site, entry.spec.config(consensus_runs=2, reruns=2))
    counts = out["counts"].filter(pl.col("t").is_between(a, b))
    assert counts.height > 0 and (counts["lower_bound"] == 0).all()
    assert out["tracks"].filter(pl.col("t").is_between(a, b)).height == 0
