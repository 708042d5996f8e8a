"""The readers' compiled state machines against the polars window versions they replace, on
random logs: the beam-pass decoder (crossings, aborted, unfinished passes, no-change rejects)
and the PIR debounce (kept and suppressed edges)."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.readers import beams as B
from onebit.readers import motion as M


def _beam_log(rng, n, *, clean):
    """Raw beam events: clean passes on 3 beams (some aborted, some left open), or random
    edges (no-change edges, interleaved pairs), with ties in time."""
    if clean:
        rows = []
        t = 0.0
        for _ in range(n // 4):
            beam = str(rng.choice(["a", "b", "c"]))
            first, other = ("a", "b") if rng.random() < 0.5 else ("b", "a")
            seq = [(first, True), (other, True), (first, False), (other, False)]
            if rng.random() < 0.2:
                seq = [(first, True), (other, True), (other, False), (first, False)]
            if rng.random() < 0.05:
                seq = seq[: int(rng.integers(1, 4))]
            for pair, blocked in seq:
                t += float(rng.choice([0.0, 0.1, 0.5]))
                rows.append((round(t, 1), beam, pair, blocked))
        f = pl.DataFrame(
            rows, schema={"t": pl.Float64, "beam": pl.String, "pair": pl.String, "blocked": pl.Boolean}, orient="row"
        )
    else:
        f = pl.DataFrame(
            {
                "t": np.sort(rng.uniform(0, 100, n)).round(1),
                "beam": rng.choice(["a", "b", "c"], n),
                "pair": rng.choice(["a", "b"], n),
                "blocked": rng.random(n) < 0.5,
            }
        )
    return f.with_columns(line=pl.int_range(2, f.height + 2, dtype=pl.Int64)).select(
        "line", "t", "beam", "pair", "blocked"
    )


@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize("clean", [True, False])
def test_beam_pass_kernel_equals_reference(seed, clean):
    rng = np.random.default_rng(seed)
    f = _beam_log(rng, int(rng.integers(0, 1500)), clean=clean)
    a, b = B.decode_passes(f, compiled=True), B.decode_passes_reference(f)
    for k in ("events", "crossings", "aborted", "unfinished", "rejects"):
        assert getattr(a, k).equals(getattr(b, k)), k


def test_beam_pass_kernel_on_an_empty_log():
    f = _beam_log(np.random.default_rng(0), 0, clean=False)
    a, b = B.decode_passes(f, compiled=True), B.decode_passes_reference(f)
    assert a.crossings.height == 0 and a.crossings.equals(b.crossings) and a.rejects.equals(b.rejects)


@pytest.mark.parametrize("seed", range(20))
def test_debounce_kernel_equals_reference(seed):
    rng = np.random.default_rng(seed)
    sensors = ["s1", "s2", "s3", "s4"]
    n = int(rng.integers(0, 1500))
    df = pl.DataFrame(
        {
            "line": np.arange(2, n + 2, dtype=np.int64),
            "t": np.sort(rng.uniform(0, 60, n)).round(int(rng.integers(1, 4))),
            "sensor": rng.choice(sensors, n),
        }
    ).with_columns(on=(pl.int_range(pl.len()).over("sensor") % 2 == 0))
    rules = {
        s: M.DebounceRules(
            chatter_window=float(rng.choice([0, 0.1, 0.3, 1.0])), min_on=float(rng.choice([0, 0.2, 0.5, 2.0]))
        )
        for s in sensors[:3]
    }
    kept, sup = M.debounce(df, sensors, rules, compiled=True)
    kept_ref, sup_ref = M.debounce_reference(df, sensors, rules)
    assert kept.equals(kept_ref) and sup.equals(sup_ref)


@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize("clean", [True, False])
def test_vectorised_beam_passes_equal_the_kernel(seed, clean):
    """The numpy version (used while numba is not loaded) gives the pass ends of the kernel's arrays."""
    from onebit.readers import kernels as K

    rng = np.random.default_rng(100 + seed)
    f = _beam_log(rng, int(rng.integers(0, 1500)), clean=clean).sort(["t", "line"])
    code = f["beam"].replace_strict(["a", "b", "c"], [0, 1, 2], return_dtype=pl.Int64).to_numpy()
    pair = (f["pair"] == "b").to_numpy().astype(np.int8)
    blocked = f["blocked"].to_numpy().astype(np.bool_)
    want = K.pass_ends(*K.beam_passes.py_func(code, pair, blocked, 3))
    got = K.beam_pass_ends_vectorised(code.astype(np.uint8), pair, blocked, 3)
    for name, w, g in zip(want._fields, want, got):
        assert np.array_equal(w, g) and w.dtype == g.dtype, name


@pytest.mark.parametrize("n_beams", [1, 4, 5, 8, 9, 16, 17, 31, 32, 70])
def test_vectorised_beam_passes_with_many_beams(n_beams):
    """Every width of the packed counters (uint8 to 4 beams, uint16 to 8, uint32 to 16, int64 to 31)
    and more beams than one holds (one running sum per 31 beams): the same ends."""
    from onebit.readers import kernels as K

    rng = np.random.default_rng(n_beams)
    n = 3000
    beam = np.repeat(rng.integers(0, n_beams, n // 4), 4)  # passes, some broken by flipped edges
    pair = np.tile(np.array([0, 1, 0, 1], np.int8), n // 4)
    blocked = np.tile(np.array([1, 1, 0, 0], np.bool_), n // 4) ^ (rng.random(n) < 0.05)
    shuffle = rng.permutation(n // 4)  # interleave some passes of different beams
    beam, pair, blocked = (a.reshape(-1, 4)[np.sort(shuffle)].reshape(-1) for a in (beam, pair, blocked))
    beam = beam.astype(np.int64)
    want = K.pass_ends(*K.beam_passes.py_func(beam, pair, blocked, n_beams))
    got = K.beam_pass_ends_vectorised(beam, pair, blocked, n_beams)
    assert want.close.size > 0
    for name, w, g in zip(want._fields, want, got):
        assert np.array_equal(w, g), name


@pytest.mark.parametrize("clean", [True, False])
def test_beam_pass_decoder_numpy_path_equals_reference(clean):
    """decode_passes above MIN_ROWS without numba loaded (the numpy pass ends) equals the polars reference."""
    rng = np.random.default_rng(7)
    f = _beam_log(rng, 6000, clean=clean)
    a, b = B.decode_passes(f, compiled="numpy"), B.decode_passes_reference(f)
    assert a.crossings.height and a.aborted.height and a.rejects.height
    for k in ("events", "crossings", "aborted", "unfinished", "rejects"):
        assert getattr(a, k).equals(getattr(b, k)), k


@pytest.mark.parametrize("seed", range(10))
def test_vectorised_toggle_repeats_and_debounce_equal_the_kernels(seed):
    """The numpy versions (used while numba is not loaded) give the kernels' masks."""
    from onebit.readers import kernels as K

    rng = np.random.default_rng(200 + seed)
    n, ns = int(rng.integers(0, 800)), 4
    sensor = rng.integers(0, ns, n).astype(np.int64)
    on = rng.random(n) < 0.5
    t = np.sort(rng.uniform(0, 60, n).round(1))
    assert np.array_equal(K.toggle_repeats.py_func(sensor, on, ns), K.toggle_repeats_vectorised(sensor, on, ns))
    alt = ~K.toggle_repeats.py_func(sensor, on, ns)  # the debounce sees alternating edges
    s2, o2, t2 = sensor[alt], on[alt], t[alt]
    chatter = rng.choice([0.0, 0.5, 2.0], ns)
    min_on = rng.choice([0.0, 1.0, 3.0], ns)
    want = K.debounce_masks.py_func(s2, o2, t2, chatter, min_on, ns, 1e-9)
    got = K.debounce_masks_vectorised(s2, o2, t2, chatter, min_on, ns, 1e-9)
    assert np.array_equal(want[0], got[0]) and np.array_equal(want[1], got[1])


@pytest.mark.parametrize("step", [1, 7, 100, 1 << 16])
@pytest.mark.parametrize("seed", range(10))
def test_fused_toggle_masks_equal_repeats_then_debounce(seed, step):
    """toggle_masks_vectorised (one sort by sensor for both passes) gives the repeats of
    toggle_repeats and, on the other edges, the masks of debounce_masks, whatever the size of
    the slices of whole sensors the debounce runs on (``step``)."""
    from onebit.readers import kernels as K

    rng = np.random.default_rng(300 + seed)
    n, ns = int(rng.integers(0, 800)), int(rng.integers(1, 6))
    sensor = rng.integers(0, ns, n).astype(np.uint32)
    on = rng.random(n) < 0.5
    t = np.sort(rng.uniform(0, 60, n).round(1))
    chatter = rng.choice([0.0, 0.5, 2.0], ns)
    min_on = rng.choice([0.0, 1.0, 3.0], ns)
    same, chat, short = K.toggle_masks_vectorised(sensor, on, t, chatter, min_on, ns, 1e-9, step=step)
    want_same = K.toggle_repeats.py_func(sensor.astype(np.int64), on, ns)
    assert np.array_equal(same, want_same)
    alt = ~want_same
    want = K.debounce_masks.py_func(sensor[alt].astype(np.int64), on[alt], t[alt], chatter, min_on, ns, 1e-9)
    assert np.array_equal(chat[alt], want[0]) and np.array_equal(short[alt], want[1])
    assert not (chat[same] | short[same]).any()


@pytest.mark.parametrize("seed", range(4))
def test_motion_reader_fused_path_equals_the_reference(tmp_path, monkeypatch, seed):
    """read_motion_csv through the fused numpy masks (numba not loaded) gives the tables of the
    polars reference path (without them, below MIN_ROWS): kept, suppressed, rejects
    and the held count, on a log with repeats, chatter, short pulses and a level sensor."""
    from onebit.core import compiled
    from onebit.readers import kernels as K

    rng = np.random.default_rng(400 + seed)
    n = 3000
    t = np.sort(rng.uniform(0, 300, n).round(2))
    sensor = rng.choice(["p1", "p2", "p3", "lv"], n)
    on = (rng.random(n) < 0.5).astype(int)
    p = tmp_path / "motion.csv"
    pl.DataFrame({"t": t, "sensor": sensor, "value": on}).write_csv(p)
    rules = {"p1": M.DebounceRules(chatter_window=0.5, min_on=1.0), "p2": M.DebounceRules(min_on=2.0)}
    kw = dict(rules=rules, held={"lv"})
    monkeypatch.setattr(compiled, "numba_loaded", lambda: False)
    monkeypatch.setattr(M, "numba_loaded", lambda: False)
    with monkeypatch.context() as mp:  # the path without the fused masks: n < MIN_ROWS, the polars references
        mp.setattr(M, "_toggle_masks", lambda *a: None)
        ref = M.read_motion_csv(p, ["p1", "p2", "p3", "lv"], **kw)
    calls = []
    real = K.toggle_masks_vectorised
    monkeypatch.setattr(K, "toggle_masks_vectorised", lambda *a: calls.append(1) or real(*a))
    fused = M.read_motion_csv(p, ["p1", "p2", "p3", "lv"], **kw)
    assert calls  # the fused path ran
    assert ref.held > 0 and ref.suppressed.height > 0 and ref.rejects.height > 0
    assert fused.motion.equals(ref.motion)
    assert fused.suppressed.equals(ref.suppressed)
    assert fused.rejects.equals(ref.rejects)
    assert fused.held == ref.held


@settings(max_examples=300, deadline=None)
@given(
    st.lists(st.tuples(st.integers(0, 2), st.integers(0, 30)), min_size=0, max_size=80),
    st.lists(st.sampled_from([0.0, 0.3, 1.0, 2.5]), min_size=3, max_size=3),
    st.lists(st.sampled_from([0.0, 0.3, 1.0, 2.5]), min_size=3, max_size=3),
)
def test_debounce_without_gathering_the_edges_left_equals_the_kernel(edges, chatter, min_on):
    """debounce_masks_vectorised (the minimum on-time rule on the neighbours both left by
    chatter and across each run of chatter pairs, no gather of the edges left) gives the
    kernel's masks on dense alternating logs: runs of chatter pairs, sensors' sequences
    meeting across a run, rules shared or per sensor, gaps at the rules' edges."""
    from onebit.readers import kernels as K

    ns = 3
    sensor = np.array([s for s, _ in edges], dtype=np.int64)
    t = np.sort(np.array([k / 10 for _, k in edges], dtype=np.float64))
    on = np.zeros(sensor.size, dtype=np.bool_)
    state = np.zeros(ns, dtype=np.bool_)
    for k, s in enumerate(sensor.tolist()):  # alternating per sensor, as the debounce sees them
        state[s] = ~state[s]
        on[k] = state[s]
    chatter, min_on = np.array(chatter), np.array(min_on)
    want = K.debounce_masks.py_func(sensor, on, t, chatter, min_on, ns, 1e-9)
    got = K.debounce_masks_vectorised(sensor, on, t, chatter, min_on, ns, 1e-9)
    assert np.array_equal(want[0], got[0]) and np.array_equal(want[1], got[1])


@settings(max_examples=60, deadline=None)
@given(
    edges=st.lists(st.tuples(st.integers(0, 69), st.integers(0, 1), st.booleans()), max_size=300),
    n_beams=st.sampled_from([1, 3, 4, 70]),
    step=st.sampled_from([1, 2, 3, 7, 64, 1 << 16]),
)
def test_beam_rejects_step_by_step_equal_the_kernel(edges, n_beams, step):
    """The no-change codes found ``step`` edges at a time (each pair's last value carried from
    step to step) are the kernel's, whatever the step: a pair's first edge in a step is compared
    with its last edge of an earlier step (it fails when the carried value is left out)."""
    from onebit.readers import kernels as K

    beam = np.array([b % n_beams for b, _, _ in edges], dtype=np.int64)
    pair = np.array([p for _, p, _ in edges], dtype=np.int8)
    blocked = np.array([v for _, _, v in edges], dtype=np.bool_)
    want = K.beam_passes.py_func(beam, pair, blocked, n_beams)[0]
    got = K.beam_rejects(beam.astype(np.uint8), pair, blocked, n_beams, step=step)
    assert got.dtype == want.dtype and np.array_equal(got, want)


@settings(max_examples=60, deadline=None)
@given(
    edges=st.lists(st.tuples(st.integers(0, 3), st.booleans()), min_size=1, max_size=200),
    data=st.data(),
    step=st.sampled_from([1, 2, 5, 1 << 16]),
)
def test_last_accepted_edge_found_from_the_end_equals_a_scan(edges, data, step):
    """The last accepted edge of a beam at or after an accepted edge ``k``, found ``step`` edges at
    a time from the end back, is the last one a scan of the whole tail finds."""
    from onebit.readers import kernels as K

    beam = np.array([b for b, _ in edges], dtype=np.uint8)
    reject = np.array([0 if ok else 1 for _, ok in edges], dtype=np.int8)
    reject[0] = 0
    k = data.draw(st.sampled_from(np.flatnonzero(reject == 0).tolist()))
    want = k + int(np.flatnonzero((beam[k:] == beam[k]) & (reject[k:] == 0))[-1])
    assert K._last_accepted(beam, reject, k, step=step) == want


@pytest.mark.parametrize("n_beams", [1, 2, 3, 4, 8])
@pytest.mark.parametrize("seed", range(4))
def test_passes_paired_by_masks_equal_paired_by_sorts(n_beams, seed):
    """The two pairings of opening and closing edges (a mask per beam for a few beams, two sorts
    beyond) give the same passes, open ones included."""
    from onebit.readers import kernels as K

    rng = np.random.default_rng(seed)
    n = 4000
    beam = np.repeat(rng.integers(0, n_beams, n // 4), 4).astype(np.uint8)
    pair = np.tile(np.array([0, 1, 0, 1], np.int8), n // 4)
    blocked = np.tile(np.array([1, 1, 0, 0], np.bool_), n // 4) ^ (rng.random(n) < 0.05)
    reject = K.beam_rejects(beam, pair, blocked, n_beams)
    ends = K.beam_pass_ends_vectorised(beam, pair, blocked, n_beams, reject=reject)
    opens = np.sort(np.concatenate([ends.opened, ends.open_first]))
    a = K._pair_by_beam_masks(beam, opens, ends.close, n_beams)
    b = K._pair_by_beam_sorts(beam, opens, ends.close, n_beams)
    assert ends.close.size > 0
    for x, y in zip(a, b):
        assert x.dtype == y.dtype and np.array_equal(x, y)
