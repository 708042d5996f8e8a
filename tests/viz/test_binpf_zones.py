"""A large array's recording by zone: the zones tile the site, each frame's tracks are counted
once in the zone holding them (the outer edge included), and the blueprint shows the counts
per zone instead of a row per sensor."""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.viz.binpf import zone_counts, zones_of


def test_zones_tile_the_site():
    names, lo, hi = zones_of((0.0, 0.0, 30.0, 15.0), n=3)
    assert names == ["A1", "B1", "C1", "A2", "B2", "C2", "A3", "B3", "C3"]
    assert np.isclose(((hi - lo).prod(axis=1)).sum(), 30.0 * 15.0)
    assert lo.min(axis=0).tolist() == [0.0, 0.0] and hi.max(axis=0).tolist() == [30.0, 15.0]


def test_each_track_counted_once_in_its_zone():
    names, lo, hi = zones_of((0.0, 0.0, 30.0, 30.0), n=3)
    times = np.array([0.0, 0.5, 1.0])
    tracks = pl.DataFrame(
        {
            "track": ["a", "b", "c", "a", "d"],
            "t": [0.0, 0.0, 0.0, 0.5, 0.7],  # 0.7 is no frame: not counted
            "x": [1.0, 10.0, 30.0, 29.0, 5.0],  # 10.0 on the A|B edge goes to B; 30.0 (outer edge) to C
            "y": [1.0, 1.0, 30.0, 15.0, 5.0],
        }
    )
    c = zone_counts(times, tracks, lo, hi)
    assert c.sum() == 4
    assert c[0, names.index("A1")] == 1 and c[0, names.index("B1")] == 1 and c[0, names.index("C3")] == 1
    assert c[1, names.index("C2")] == 1
    assert c[2].sum() == 0


def test_zone_labels_read_back_from_the_recording(tmp_path):
    from onebit.viz import paths
    from onebit.viz.binpf import log_zones
    from onebit.viz.inspect import timed_rows
    from onebit.viz.recording import stage_recording

    times = np.array([0.0, 0.5])
    tracks = pl.DataFrame(
        {"track": ["a", "b", "b"], "t": [0.0, 0.0, 0.5], "x": [1.0, 2.0, 25.0], "y": [1.0, 2.0, 25.0]}
    )
    with stage_recording(tmp_path, "binpf", "run-1") as rec:
        log_zones(rec, "binpf", times, tracks, (0.0, 0.0, 30.0, 30.0))
    rows = timed_rows(
        tmp_path / "rrd" / "binpf.rrd", paths.join(paths.tracker_root("binpf"), "zones", "labels"), "Points2D:labels"
    )
    assert [r[0] for r in rows] == times.tolist()
    assert "A1: 2" in rows[0][1] and "C3: 0" in rows[0][1]
    assert "A1: 0" in rows[1][1] and "C3: 1" in rows[1][1]
    assert len(rows[0][1]) == 9  # nine labels a frame, not one per sensor
