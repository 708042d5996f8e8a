"""The irtracking formats (Milan et al.'s ceiling array): readings txt, CVML, sensor coordinates."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.core.errors import InputError
from onebit.datasets.irtracking_sim import coordinates_m, cvml, sensor_grid, write_irtracking
from onebit.readers.irtracking import PIXEL_MM, read_cvml, read_readings_txt, read_sensor_coordinates


def test_simulated_files_read_back(tmp_path):
    f = write_irtracking(tmp_path, frames=30, people=2, seed=3)
    rd = read_readings_txt(f.readings, sensors=len(f.sensors_mm))
    assert rd.frames == 30 and rd.rejects.height == 0 and rd.start.isoformat() == "2013-09-25T15:47:25"
    got = {fr: sorted(int(s) for s in g["sensor"]) for (fr,), g in rd.active.group_by("frame")}
    assert got == {fr: v for fr, v in f.active.items() if v}
    xy = read_sensor_coordinates(f.coordinates)
    assert np.array_equal(xy, np.round(f.sensors_mm))
    gt = read_cvml(f.truth)
    assert gt.frames == tuple(range(1, 31)) and gt.rejects.height == 0
    row = gt.objects.filter(frame=30, object="1").row(0, named=True)
    assert row["x"] == pytest.approx(f.truth_mm[30][1][0], abs=1e-3 * PIXEL_MM)
    det = read_cvml(f.detections)
    assert det.objects["object"].null_count() == det.objects.height == rd.active.height


@settings(max_examples=40, deadline=None)
@given(st.lists(st.lists(st.integers(0, 1), min_size=50, max_size=50), min_size=1, max_size=12), st.booleans())
def test_readings_round_trip(tmp_path_factory, matrix, crlf):
    """Any 0/1 matrix written as the authors' lines (the sensor's number where active) reads
    back as its non-zero cells, frames numbered from 1; channels 44-50 are counted, not read."""
    m = np.asarray(matrix) * np.arange(1, 51)[None, :]
    text = ("\r\n" if crlf else "\n").join(["2013-9-19 16:12:40", *(" ".join(map(str, r)) + " " for r in m)])
    path = tmp_path_factory.mktemp("rd") / "s.txt"
    path.write_text(text)
    rd = read_readings_txt(path)
    f, s = np.nonzero(m[:, :43])
    assert rd.frames == len(m)
    assert sorted(zip(rd.active["frame"], rd.active["sensor"].cast(int))) == sorted(zip(f + 1, s + 1))
    assert rd.extra_active == int(np.count_nonzero(m[:, 43:]))


def test_bad_reading_lines_are_rejected_with_their_line(tmp_path):
    ok = " ".join(["0"] * 50)
    path = tmp_path / "s.txt"
    path.write_text("\n".join(["2013-9-19 16:12:40", ok, "0 0 5", ok.replace("0", "x", 1), ok]))
    rd = read_readings_txt(path)
    assert rd.frames == 2
    assert rd.rejects["line"].to_list() == [3, 4]
    assert "3 fields, expected 50" in rd.rejects["reason"][0] and "not an integer" in rd.rejects["reason"][1]
    path.write_text("2013-9-19 16:12:40\n1 2 3\n")
    with pytest.raises(InputError, match="no reading line"):
        read_readings_txt(path)


def test_cvml_problems_name_file_and_line(tmp_path):
    p = tmp_path / "gt.xml"
    p.write_text(cvml({1: [("1", 1000.0, 2000.0)], 2: []}).replace('xc="40.0000"', 'xc="abc"'))
    res = read_cvml(p)
    assert res.frames == (1, 2) and res.objects.height == 0
    assert res.rejects.height == 1 and res.rejects["line"][0] == 6 and "numeric" in res.rejects["reason"][0]
    p.write_text(cvml({1: [], 2: []}).replace('number="2"', 'number="1"'))
    with pytest.raises(InputError, match=r"gt.xml:\d+: field 'number': frame 1 appears twice"):
        read_cvml(p)
    p.write_text("<dataset><frame number='1'></dataset>")
    with pytest.raises(InputError, match="not well-formed"):
        read_cvml(p)


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 5), st.integers(1, 9), st.floats(300, 3000))
def test_coordinates_round_trip(tmp_path_factory, cols, rows, spacing):
    xy = np.round(sensor_grid(cols, rows, spacing))
    p = tmp_path_factory.mktemp("c") / "getSensorCoordinates.m"
    p.write_text(coordinates_m(xy))
    assert np.array_equal(read_sensor_coordinates(p), xy)


def test_coordinates_errors(tmp_path):
    p = tmp_path / "getSensorCoordinates.m"
    p.write_text("xc=[1 2 3];\n% yc=[1 2 3];\n")
    with pytest.raises(InputError, match="field 'yc'"):
        read_sensor_coordinates(p)
    p.write_text("xc=[1 2 3];\nyc=[1 2];\n")
    with pytest.raises(InputError, match="one per sensor"):
        read_sensor_coordinates(p)
    p.write_text("xc=[1 2 zz];\nyc=[1 2 3];\n")
    with pytest.raises(InputError, match="'zz' is not a number"):
        read_sensor_coordinates(p)
