"""Slots and the empty room (:mod:`onebit.core.frames`): frames against a brute force, the
refractory recursion, silent stretches and the estimates kept outside them."""

from __future__ import annotations

import math

import polars as pl
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.core.errors import ConfigError
from onebit.core.frames import SILENT, motion_frames, outside_silence, refractory_state, silent_stretches
from onebit.core.tables import FRAMES, MOTION

SENSORS = ("p1", "p2", "p3")


def frames_reference(edges, sensors, period, t0, n):
    """Per slot and sensor by brute force: state at slot start, any rising edge in the slot."""
    out = []
    for k in range(n):
        a, b = t0 + k * period, t0 + (k + 1) * period
        for s in sensors:
            mine = [(t, on) for t, ss, on in edges if ss == s]
            state = False
            for t, on in mine:
                if t <= a:
                    state = on
            fired = any(on and a <= t < b for t, on in mine)
            out.append((k, s, state or fired, fired))
    return out


@given(
    st.lists(st.tuples(st.floats(0, 30).map(lambda v: round(v, 2)), st.sampled_from(SENSORS)), max_size=30),
    st.sampled_from([0.5, 1.0, 2.0]),
)
@settings(max_examples=80, deadline=None)
def test_frames_match_brute_force(stamps, period):
    rows = sorted(stamps)
    # make an alternating log per sensor from the time stamps
    count = {s: 0 for s in SENSORS}
    edges = []
    for t, s in rows:
        edges.append((t, s, count[s] % 2 == 0))
        count[s] += 1
    motion = pl.DataFrame(edges, schema=MOTION, orient="row")
    fr = motion_frames(motion, SENSORS, period=period, t0=0.0, t1=32.0)
    assert fr.schema == FRAMES
    n = math.ceil(32.0 / period)
    assert fr.height == n * len(SENSORS)
    got = list(zip(fr["slot"].to_list(), fr["sensor"].to_list(), fr["on"].to_list(), fr["fired"].to_list()))
    assert got == frames_reference(edges, SENSORS, period, 0.0, n)
    assert fr["t"].to_list() == pytest.approx([k * period for k in range(n) for _ in SENSORS])


def test_frames_default_span_is_aligned():
    motion = pl.DataFrame([(5.3, "p1", True), (9.9, "p1", False)], schema=MOTION, orient="row")
    fr = motion_frames(motion, ["p1"], period=2.0)
    assert fr["t"].to_list() == [4.0, 6.0, 8.0]
    assert fr["fired"].to_list() == [True, False, False] and fr["on"].to_list() == [True, True, True]
    assert motion_frames(motion.clear(), ["p1"], period=2.0).height == 0
    with pytest.raises(ConfigError, match="period"):
        motion_frames(motion, ["p1"], period=0.0)


@given(st.lists(st.booleans(), max_size=40), st.sampled_from([0.0, 2.0, 4.0, 5.0, 16.0]))
@settings(max_examples=80, deadline=None)
def test_refractory_state_follows_the_recursion(fired, f):
    period = 2.0
    frames = pl.DataFrame(
        {
            "slot": list(range(len(fired))),
            "t": [k * period for k in range(len(fired))],
            "sensor": ["p1"] * len(fired),
            "on": fired,
            "fired": fired,
        },
        schema=FRAMES,
    )
    st_ = refractory_state(frames, {"p1": f}, period=period)
    beta, want_beta, want_blind = 0.0, [], []
    for s in fired:  # beta_tau = f if S else max(0, beta_{tau-1} - t_P); blind = beta_{tau-1} > 0
        want_blind.append(beta > 0)
        beta = f if s else max(0.0, beta - period)
        want_beta.append(beta)
    assert st_["beta"].to_list() == pytest.approx(want_beta)
    assert st_["blind"].to_list() == want_blind


# --------------------------------------------------------------------------- the empty room


def _edges(rows):
    return pl.DataFrame(rows, schema=MOTION, orient="row")


def test_silent_stretches_are_the_long_gaps_with_every_sensor_off():
    motion = _edges(
        [
            (0.0, "p1", True),
            (5.0, "p1", False),
            (100.0, "p2", True),
            (101.0, "p2", False),
            (110.0, "p1", True),
            (120.0, "p1", False),
        ]
    )
    crossings = pl.DataFrame({"t": [50.0], "sensor": ["b1"]})
    assert silent_stretches([motion], min_s=60.0).rows() == [(5.0, 100.0)]
    # an event without `on` (a crossing) breaks the silence; the stretch after the last event is not data
    assert silent_stretches([motion, crossings], min_s=30.0).rows() == [(5.0, 50.0), (50.0, 100.0)]
    # a sensor on through the gap keeps someone present; a repeated `on` counts once
    held = _edges([(0.0, "p3", True), (1.0, "p3", True), (200.0, "p3", False)])
    assert silent_stretches([motion, held], min_s=60.0).height == 0
    assert silent_stretches([motion], min_s=0.0).schema == SILENT and silent_stretches([motion], min_s=0.0).height == 0
    assert silent_stretches([], min_s=60.0).height == 0


def test_outside_silence_drops_only_the_rows_strictly_inside():
    silent = pl.DataFrame({"t_start": [5.0], "t_end": [100.0]}, schema=SILENT)
    tracks = pl.DataFrame({"t": [50.0, 5.0, 1.0, 100.0, 99.9], "x": [1.0, 2.0, 3.0, 4.0, 5.0]})
    kept = outside_silence(tracks, silent)
    assert kept["t"].to_list() == [5.0, 1.0, 100.0] and kept.columns == tracks.columns  # order and columns kept
    assert outside_silence(tracks, silent.clear()).equals(tracks)
