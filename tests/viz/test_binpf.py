"""onebit.viz.binpf: the footprints of the sensors on, read back from the .rrd -- each frame
holds one ring per sensor on, around that sensor, at the frame's time."""

from __future__ import annotations

import numpy as np

from onebit.viz import paths
from onebit.viz.binpf import log_footprints
from onebit.viz.inspect import timed_rows
from onebit.viz.recording import stage_recording


def test_each_frame_holds_the_ring_of_every_sensor_on(tmp_path):
    rng = np.random.default_rng(3)
    sensors = rng.uniform(0.0, 10.0, (6, 2))
    radii = rng.uniform(0.5, 1.5, 6)
    on = rng.random((9, 6)) < 0.4
    on[4] = False  # a frame with nothing on
    t = np.arange(9) * 0.5
    with stage_recording(tmp_path, "binpf", "run-1") as rec:
        log_footprints(rec, "binpf", t, on, sensors, radii)
    rows = timed_rows(
        tmp_path / "rrd" / "binpf.rrd", paths.join(paths.tracker_root("binpf"), "sensors", "on"), "LineStrips2D:strips"
    )
    assert [r[0] for r in rows] == t.tolist()
    for (_, strips), row in zip(rows, on):
        assert len(strips) == int(row.sum())
        for got, s in zip(strips, np.flatnonzero(row)):
            p = np.array(got, dtype=float)
            assert p.shape == (25, 2)
            np.testing.assert_allclose(np.hypot(*(p - sensors[s]).T), radii[s], rtol=1e-5)
