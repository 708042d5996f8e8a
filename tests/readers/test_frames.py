"""Frame-sampled logs (``frames.csv``): list, long and wide layouts read to the same levels."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.core.errors import InputError
from onebit.core.tables import FRAMES
from onebit.readers.frames import edges_of_levels, frame_log_layout, read_frames_csv
from onebit.readers.motion import read_motion_csv

SENSORS = ["a", "b", "c"]


def write_layouts(folder, t, grid, sensors=SENSORS):
    """The same frames as list, long and wide ``frames.csv`` files."""
    lst = ["t,active"] + [f"{ti},{' '.join(s for s, v in zip(sensors, row) if v)}" for ti, row in zip(t, grid)]
    long = ["t,sensor,value"] + [f"{ti},{s},{int(v)}" for ti, row in zip(t, grid) for s, v in zip(sensors, row)]
    wide = ["t," + ",".join(sensors)] + [f"{ti}," + ",".join(str(int(v)) for v in row) for ti, row in zip(t, grid)]
    out = {}
    for name, lines in (("list", lst), ("long", long), ("wide", wide)):
        p = folder / name / "frames.csv"
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text("\n".join(lines) + "\n")
        out[name] = p
    return out


@settings(max_examples=30, deadline=None)
@given(st.lists(st.lists(st.booleans(), min_size=3, max_size=3), min_size=1, max_size=15))
def test_three_layouts_give_the_same_levels(tmp_path_factory, rows):
    grid = np.asarray(rows, dtype=bool)
    t = [0.5 * k for k in range(len(grid))]
    paths = write_layouts(tmp_path_factory.mktemp("f"), t, grid)
    logs = {k: read_frames_csv(p, SENSORS) for k, p in paths.items()}
    for name, log in logs.items():
        assert log.layout == name and log.frames == len(grid) and log.rejects.height == 0 and log.unlisted == 0
        assert log.levels.schema == FRAMES
        assert (
            log.levels.height == len(grid) * 3
        )  # every frame x every sensor: held-on frames are kept, never "no state change"
        assert log.levels["on"].to_numpy().reshape(-1, 3).tolist() == grid.tolist()
        prev = np.vstack([np.zeros((1, 3), bool), grid[:-1]])
        assert log.levels["fired"].to_numpy().reshape(-1, 3).tolist() == (grid & ~prev).tolist()
    edges = edges_of_levels(logs["list"].levels)
    # the edges replay to the levels: a sensor's state at each frame is its last edge's
    for j, s in enumerate(SENSORS):
        e = edges.filter(sensor=s)
        state = np.zeros(len(grid), bool)
        for ti, on in e.select("t", "on").iter_rows():
            state[int(round(ti / 0.5)) :] = on
        assert state.tolist() == grid[:, j].tolist()
        assert e["on"].to_list() == [k % 2 == 0 for k in range(e.height)]  # alternating, starting on


def test_bad_rows_are_rejected_with_line_and_reason(tmp_path):
    p = tmp_path / "frames.csv"
    p.write_text("t,active\n0,a b\n0.5,a zz\n0.5,c\nx,a\n1.0,\n0.7,b\n")
    log = read_frames_csv(p, SENSORS)
    assert log.frames == 3  # t = 0, 0.5 (line 4), 1.0
    reasons = dict(zip(log.rejects["line"].to_list(), log.rejects["reason"].to_list()))
    assert "unknown sensor 'zz'" in reasons[3]  # the whole frame's row, never half taken
    assert "not a number" in reasons[5]
    assert set(reasons) == {3, 5, 7}  # 0.7 after 1.0: goes backwards
    on = log.levels.filter("on").select("t", "sensor").rows()
    assert on == [(0.0, "a"), (0.0, "b"), (0.5, "c")]


def test_long_and_wide_unlisted_sensors_are_off_and_counted(tmp_path):
    p = tmp_path / "frames.csv"
    p.write_text("t,sensor,value\n0,a,1\n0,b,0\n0.5,a,ON\n0.5,a,1\n")
    log = read_frames_csv(p, SENSORS)
    assert log.layout == "long" and log.unlisted == 6 - 3
    assert "duplicate" in log.rejects["reason"][0]
    p.write_text("t,a,c\n0,1,0\n0.5,1,1\n")
    log = read_frames_csv(p, SENSORS)
    assert log.layout == "wide" and log.unlisted == 2  # b has no column
    assert log.levels.filter("on").select("t", "sensor").rows() == [(0.0, "a"), (0.5, "a"), (0.5, "c")]
    p.write_text("t,a,nope\n0,1,0\n")
    with pytest.raises(InputError, match="field 'nope'"):
        read_frames_csv(p, SENSORS)


def test_layout_needs_t():
    assert frame_log_layout(["t", "active"]) == "list"
    assert frame_log_layout(["t", "sensor", "value"]) == "long"
    assert frame_log_layout(["t", "S1", "S2"]) == "wide"
    with pytest.raises(InputError, match="field 't'"):
        frame_log_layout(["time", "active"])


def test_empty_log(tmp_path):
    p = tmp_path / "frames.csv"
    p.write_text("")
    log = read_frames_csv(p, SENSORS)
    assert log.frames == 0 and log.levels.height == 0 and log.period is None
    assert edges_of_levels(log.levels).height == 0
    assert isinstance(log.levels, pl.DataFrame)


def test_a_sampled_toggle_log_of_level_sensors_is_not_rejected(tmp_path):
    """One 0/1 per sensor per frame in motion.csv: for level sensors the repeats are held
    states (counted), for edge sensors (a PIR's trigger) they stay rejects."""
    p = tmp_path / "motion.csv"
    grid = [[1, 0], [1, 0], [1, 1], [0, 1], [0, 0], [0, 0]]
    p.write_text(
        "t,sensor,value\n" + "".join(f"{k},{s},{v}\n" for k, row in enumerate(grid) for s, v in zip("ab", row))
    )
    lv = read_motion_csv(p, ["a", "b"], held={"a", "b"})
    assert lv.rejects.height == 0 and lv.held == 12 - 4
    assert lv.motion.rows() == [(0.0, "a", True), (2.0, "b", True), (3.0, "a", False), (4.0, "b", False)]
    edge = read_motion_csv(p, ["a", "b"])
    assert edge.rejects.height == 8 and edge.held == 0 and edge.motion.rows() == lv.motion.rows()
