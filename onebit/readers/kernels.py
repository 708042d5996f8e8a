"""Compiled (numba) state machines of the readers: the directional-beam pass decoder
(Bobadilla et al., Fig. 7) and the PIR debounce.

Both walk the accepted events once in time order with a little state per beam or sensor --
inherently sequential per beam / sensor -- so they are compiled loops
(``numba.njit(cache=True)``, :mod:`onebit.core.compiled`); they only classify rows (which edge is a no-change, which
passes close, which edges a debounce rule suppresses), and the readers build their tables
from the result with polars. Each keeps the polars expression version it replaces as its
plain reference and test oracle (``tests/readers/test_kernels.py``: equal crossings, aborted
and unfinished passes, rejects, kept and suppressed edges on random logs):

=============================  ===============================================================
kernel                         reference
=============================  ===============================================================
:func:`beam_passes`            :func:`onebit.readers.beams.decode_passes_reference`
:func:`debounce_masks`         :func:`onebit.readers.motion.debounce_reference`
=============================  ===============================================================
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from onebit.core.compiled import kernel

#: Rows from which the readers use the kernels (``compiled=None``). Below it the polars
#: reference is as fast, and a fresh process would pay numba's start (0.3-1 s, once) for it.
MIN_ROWS = 20_000

#: No-change reasons of :func:`beam_passes` (0 = accepted).
ALREADY_BLOCKED, ALREADY_CLEAR = 1, 2


@kernel
def beam_passes(beam, pair, blocked, n_beams):
    """Decode events sorted by time (``beam`` index, ``pair`` 0 = a / 1 = b, ``blocked``).

    An edge that leaves its pair's state unchanged is rejected (``reject`` code, see
    :data:`ALREADY_BLOCKED`); the others drive each beam's pass machine: a pass runs from
    the first edge after an idle state (both pairs clear) to the edge that makes the beam
    idle again. Returns ``(reject (m,), pass_first (m,), close (m,), first_pair (m,), last
    (n_beams,))``: for every accepted edge the index of the first edge of its pass; ``close``
    marks the edges that close a pass and ``first_pair`` (on those) the pair that opened it;
    ``last`` is each beam's last accepted edge (-1: none). A pass without a closing edge is
    still open at the end of the log (unfinished): the one holding its beam's last edge, if
    that edge does not close it.
    """
    m = beam.shape[0]
    reject = np.zeros(m, dtype=np.int8)
    pass_first = np.empty(m, dtype=np.int64)
    close = np.zeros(m, dtype=np.bool_)
    first_pair = np.full(m, -1, dtype=np.int8)
    state = np.zeros(2 * n_beams, dtype=np.bool_)  # pair q of beam b at 2 b + q
    opened = np.full(n_beams, -1, dtype=np.int64)  # first edge of the open pass of each beam
    opener = np.zeros(n_beams, dtype=np.int8)
    last = np.full(n_beams, -1, dtype=np.int64)
    for k in range(m):  # time order; each beam's machine only sees its own edges
        b, q, v = beam[k], pair[k], blocked[k]
        i = 2 * b + q
        if state[i] == v:  # no state change: not an edge a body makes
            reject[k] = ALREADY_BLOCKED if v else ALREADY_CLEAR
            pass_first[k] = -1
            continue
        state[i] = v
        last[b] = k
        o = opened[b]
        if o < 0:
            o = k
            opened[b] = k
            opener[b] = q
        pass_first[k] = o
        if not (state[2 * b] | state[2 * b + 1]):  # idle again: the pass closes here
            close[k] = True
            first_pair[k] = opener[b]
            opened[b] = -1
    return reject, pass_first, close, first_pair, last


class PassEnds(NamedTuple):
    """The passes of a beam log as :func:`decode_passes <onebit.readers.beams.decode_passes>`
    needs them (indices into the events, in time order): ``reject`` (m,) the no-change code of
    each edge (0 = accepted); ``close`` the edges that close a pass, ascending, and ``opened``
    the first edge of each one's pass; ``open_last`` the last edge of each beam whose pass is
    still open at the end, and ``open_first`` that pass's first edge, both in the order the
    open passes started."""

    reject: np.ndarray
    close: np.ndarray
    opened: np.ndarray
    open_last: np.ndarray
    open_first: np.ndarray


def pass_ends(reject, pass_first, close, first_pair, last) -> PassEnds:
    """:class:`PassEnds` from the five arrays of :func:`beam_passes` (the kernel)."""
    ends = np.flatnonzero(close)
    op = last[last >= 0]
    op = op[~close[op]]
    op = op[np.argsort(pass_first[op], kind="stable")]
    return PassEnds(reject, ends, pass_first[ends], op, pass_first[op])


#: Beams per packed counter of :func:`beam_pass_ends_vectorised` (2 bits each in an int64), and
#: the most beams whose counters fit one uint32 (uint16 up to 8 beams, uint8 up to 4: less memory).
_PACK, _PACK32 = 31, 16


#: Edges per step of :func:`beam_rejects`: its sort and temporaries stay small (a few hundred KiB,
#: reused from step to step, in cache) instead of 10^6-row arrays touched once each.
_REJECT_STEP = 1 << 16


def beam_rejects(beam, pair, blocked, n_beams, *, step: int = _REJECT_STEP) -> np.ndarray:
    """The no-change code of every edge (0 = accepted; :data:`ALREADY_BLOCKED`,
    :data:`ALREADY_CLEAR`) of :func:`beam_pass_ends_vectorised`: after a stable radix sort by
    (beam, pair), an edge equal to its pair's previous edge (clear before the first).

    The edges are taken ``step`` at a time in time order, each step sorted alone: an edge's
    previous edge of its pair is the one before it in its step's sort, or, for the first edge of
    its pair in the step, the pair's last edge of the steps before (each pair's last value is
    carried from step to step; every pair starts clear). The same codes as one sort of all the
    edges (tests: any ``step`` against the kernel), with small temporaries: a sort of 10^6 edges
    at once allocates two 8 MB index arrays, 4 000 first-touch page faults in a fresh process."""
    beam = np.asarray(beam)
    pair = np.asarray(pair)
    blocked = np.asarray(blocked, np.bool_)
    m = beam.shape[0]
    reject = np.zeros(m, dtype=np.int8)
    if m == 0:
        return reject
    small = _key_type(2 * n_beams)
    last = np.zeros(2 * n_beams, dtype=np.bool_)  # each pair's value after the steps before (clear at first)
    step = max(1, int(step))
    for lo in range(0, m, step):
        hi = min(m, lo + step)
        g = beam[lo:hi].astype(small)
        g <<= 1
        g |= pair[lo:hi].astype(small)
        order = np.argsort(g, kind="stable")  # per (beam, pair), in time order (a radix sort)
        vs = blocked[lo:hi][order]
        gs = g[order]
        same = np.empty(hi - lo, dtype=np.bool_)
        np.equal(vs[1:], vs[:-1], out=same[1:])
        starts = np.flatnonzero(gs[1:] != gs[:-1]) + 1
        starts = np.concatenate([[0], starts])
        same[starts] = vs[starts] == last[gs[starts]]  # a pair's first edge in the step: against its last before
        ends = np.append(starts[1:] - 1, hi - lo - 1)
        last[gs[ends]] = vs[ends]
        bad_sorted = np.flatnonzero(same)
        reject[lo + order[bad_sorted]] = np.where(vs[bad_sorted], ALREADY_BLOCKED, ALREADY_CLEAR)
    return reject


#: Beams up to which :func:`beam_pass_ends_vectorised` pairs the opening and closing edges of
#: each beam by a mask per beam (two scans of the edges each) rather than by two sorts.
_FEW_BEAMS = 8


def _pair_by_beam_sorts(beam, opens, close, n_beams) -> tuple[np.ndarray, np.ndarray]:
    """``(opened, open_first)`` of :func:`beam_pass_ends_vectorised`: the ``i``-th closing edge
    of a beam closes the pass its ``i``-th opening edge opened, paired by one stable radix sort of
    each by beam; a beam with one opening edge more holds an open pass, opened by its last."""
    key = _key_type(n_beams)
    ob, cb = beam[opens].astype(key), beam[close].astype(key)
    o_order = np.argsort(ob, kind="stable")
    c_order = np.argsort(cb, kind="stable")
    n_open = np.bincount(ob, minlength=n_beams)
    n_close = np.bincount(cb, minlength=n_beams)
    o_start = np.cumsum(n_open) - n_open  # where each beam's opening edges start in o_order
    c_start = np.cumsum(n_close) - n_close
    # the i-th closing edge of a beam (sorted position c_start[b] + i) closes its i-th opening edge's pass
    to_open = np.arange(close.size, dtype=np.int64) + np.repeat(o_start - c_start, n_close)
    opened = np.empty(close.size, dtype=np.int64)
    opened[c_order] = opens[o_order[to_open]]
    # a beam with one more opening than closing edge: its last pass is open at the end
    left = np.flatnonzero(n_open > n_close)
    return opened, np.sort(opens[o_order[o_start[left] + n_open[left] - 1]])


def _pair_by_beam_masks(beam, opens, close, n_beams) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_pair_by_beam_sorts` with a mask per beam: the beam's opening edges (in time order)
    taken out, the first as many as its closing edges written at those (few beams: no sort, no
    index array of all the edges)."""
    ob, cb = beam[opens], beam[close]
    opened = np.empty(close.size, dtype=np.int64)
    first = []
    for b in range(n_beams):
        mine = opens[ob == b]
        at = cb == b
        k = int(np.count_nonzero(at))
        opened[at] = mine[:k]
        if mine.size > k:  # one opening edge more: its pass is open at the end
            first.append(int(mine[-1]))
    return opened, np.array(sorted(first), dtype=np.int64)


def _last_accepted(beam, reject, k: int, step: int = 1 << 16) -> int:
    """The last accepted edge of edge ``k``'s beam (``k`` accepted), looked for from the end of
    the log back, ``step`` edges at a time (found in the last step, as a rule)."""
    hi = beam.shape[0]
    while hi > k:
        lo = max(k, hi - step)
        tail = np.flatnonzero((beam[lo:hi] == beam[k]) & (reject[lo:hi] == 0))
        if tail.size:
            return lo + int(tail[-1])
        hi = lo
    return k


def beam_pass_ends_vectorised(beam, pair, blocked, n_beams, reject=None) -> PassEnds:
    """:func:`beam_passes` as :class:`PassEnds`, with numpy array operations and no per-edge
    pass index: what a reader uses where numba is not loaded (loading it costs 0.3-0.5 s, several
    times this at 10^6 edges); the kernel's arrays give the same :class:`PassEnds` through
    :func:`pass_ends` (tests: equal on random logs).

    No-change edges: a pair's state before an edge is its previous edge's value (an accepted
    edge sets it, a rejected one had it already), so after a stable radix sort by (beam, pair)
    an edge equal to its pair's previous edge (clear before the first) is rejected. The
    accepted edges of each pair alternate, blocked first, so the number of blocked pairs of
    beam ``b`` after edge ``k`` is the running sum over the beam's accepted edges of ``+1``
    (blocked) / ``-1`` (cleared), a rejected edge adding 0::

        c_b(k) = sum_{j <= k, beam_j = b, accepted} (2 blocked_j - 1)  in {0, 1, 2}

    so one cumulative sum of ``(2 blocked - 1) 4^b`` over the edges in time order holds every
    beam's count in two bits (31 beams per int64; more beams, one sum per 31). An accepted
    edge opens a pass when its beam's count after it is 1 and it blocks (0 before), and closes
    one when the count after it is 0. Per beam, opening and closing edges alternate (open
    first), so the ``i``-th closing edge of a beam closes the pass its ``i``-th opening edge
    opened: one stable radix sort of each by beam pairs them, and a beam with one opening edge
    more holds an open pass (unfinished) ending at its last accepted edge. ``reject``: the
    no-change codes when already found (:func:`beam_rejects`)."""
    beam = np.asarray(beam)
    blocked = np.asarray(blocked, np.bool_)
    m = beam.shape[0]
    reject = beam_rejects(beam, pair, blocked, n_beams) if reject is None else reject
    none = np.empty(0, dtype=np.int64)
    if m == 0:
        return PassEnds(reject, none, none, none, none)
    bad = np.flatnonzero(reject)
    if n_beams <= _PACK32:  # 2 bits per beam in one unsigned word: its sums mod 2^bits are exact (counts 0..2)
        word = np.uint8 if n_beams <= 4 else np.uint16 if n_beams <= 8 else np.uint32
        shift = beam.astype(word)
        shift <<= 1
        after = blocked.astype(word)
        after <<= 1
        after -= 1  # -1 as 2^bits - 1: the sum is taken mod 2^bits
        after[bad] = 0  # a rejected edge changes no count
        after <<= shift
        np.cumsum(after, dtype=word, out=after)
        after >>= shift
        after &= 3
    else:  # int64 sums, one per 31 beams
        step = blocked.astype(np.int64)
        step <<= 1
        step -= 1
        step[bad] = 0
        after = np.empty(m, dtype=np.int64)
        for lo in range(0, n_beams, _PACK):
            rows = np.flatnonzero((beam >= lo) & (beam < lo + _PACK)) if n_beams > _PACK else slice(None)
            shift = 2 * (beam[rows].astype(np.int64) - lo)
            after[rows] = (np.cumsum(step[rows] << shift) >> shift) & 3
    mask = after == 0  # idle after a clearing edge: it closes a pass (masks made in place: no temporaries)
    np.greater(mask, blocked, out=mask)
    mask[bad] = False
    close = np.flatnonzero(mask)
    np.equal(after, 1, out=mask)  # count 1 after a blocking edge: it opens one
    mask &= blocked
    mask[bad] = False
    opens = np.flatnonzero(mask)
    del mask
    if opens.size == 0:
        return PassEnds(reject, none, none, none, none)
    if n_beams <= _FEW_BEAMS:
        opened, open_first = _pair_by_beam_masks(beam, opens, close, n_beams)
    else:
        opened, open_first = _pair_by_beam_sorts(beam, opens, close, n_beams)
    open_last = np.empty(open_first.size, dtype=np.int64)
    for i, k in enumerate(open_first.tolist()):  # the beam's last accepted edge, at or after its pass opened
        open_last[i] = _last_accepted(beam, reject, k)
    return PassEnds(reject, close, opened, open_last, open_first)


@kernel
def debounce_masks(sensor, on, t, chatter, min_on, n_sensors, eps):
    """The PIR debounce on alternating edges sorted by time (``sensor`` index, ``on``, ``t``;
    per sensor ``chatter`` window and ``min_on`` time, 0 = off).

    Chatter: an off edge followed by an on edge of the same sensor within the window drops
    both. Then, on the remaining edges, minimum on-time: an on edge followed by an off edge
    sooner than ``min_on`` drops both. Returns ``(chat (m,), short (m,))`` masks. One pass:
    an edge's chatter mark is final once its sensor's next edge is seen, and from then on it
    feeds that sensor's minimum on-time rule (per sensor, in order, as a second pass would).
    """
    m = sensor.shape[0]
    chat = np.zeros(m, dtype=np.bool_)
    short = np.zeros(m, dtype=np.bool_)
    last = np.full(n_sensors, -1, dtype=np.int64)  # each sensor's previous edge
    kept = np.full(n_sensors, -1, dtype=np.int64)  # each sensor's last edge chatter left
    for k in range(m + n_sensors):  # one pass; then each sensor's last edge
        if k < m:
            s = sensor[k]
            j = last[s]
            last[s] = k
            if j < 0:
                continue
            w = chatter[s]  # chatter: each (off, on) pair of neighbours in a sensor's sequence
            if w > 0 and on[k] and not on[j] and t[k] - t[j] <= w + eps:
                chat[j] = True
                chat[k] = True
        else:
            s = k - m
            j = last[s]
            if j < 0:
                continue
        if chat[j]:  # j's next edge is seen: whether chatter drops it is final
            continue
        i = kept[s]  # minimum on-time: (on, off) neighbours among the edges chatter left
        kept[s] = j
        mo = min_on[s]
        if i >= 0 and mo > 0 and on[i] and not on[j] and t[j] - t[i] < mo - eps:
            short[i] = True
            short[j] = True
    return chat, short


@kernel
def separators_per_line(buf, sep):
    """How many ``sep`` bytes each line of ``buf`` (uint8; lines end at ``\\n``) holds: one
    entry per line, the text after the last ``\\n`` being a line (empty at the end of a file
    that ends with one). One pass over the bytes; the numpy reference is
    :func:`onebit._testing.reader_oracles.separators_per_line_reference`."""
    n_lines = 1
    for i in range(buf.shape[0]):
        if buf[i] == 10:
            n_lines += 1
    out = np.zeros(n_lines, dtype=np.int64)
    k = 0
    for i in range(buf.shape[0]):
        c = buf[i]
        if c == 10:
            k += 1
        elif c == sep:
            out[k] += 1
    return out


def separators_per_line_vectorised(buf: np.ndarray, sep: int, step: int = 1 << 22) -> np.ndarray:
    """:func:`separators_per_line` with numpy, ``step`` bytes at a time (bounded temporaries):
    what a reader uses while numba is not loaded (its load costs 0.3-0.5 s, ten times this on a
    16 MB file). In each step the offsets of the separators and newlines, in order, are found
    at once; the separators of a line are the offsets between two newlines, plus those carried
    from the step before. Equal to :func:`onebit._testing.reader_oracles.separators_per_line_reference` (tests)."""
    out, carry = [], 0
    for lo in range(0, buf.shape[0], step):
        block = buf[lo : lo + step]
        pos = np.flatnonzero((block == sep) | (block == 10))
        nl = np.flatnonzero(block[pos] == 10)  # which of them are newlines
        if nl.size == 0:
            carry += pos.size
            continue
        counts = np.diff(nl, prepend=-1) - 1  # separators between consecutive newlines
        counts[0] += carry
        out.append(counts)
        carry = pos.size - 1 - int(nl[-1])
    out.append(np.array([carry]))
    return np.concatenate(out).astype(np.int64)


def _key_type(n: int):
    """The smallest signed integer type that holds the codes ``0 .. n - 1``: numpy's stable sort
    of 8- and 16-bit keys is a radix sort, and 8-bit keys sort twice as fast as 16-bit ones."""
    if n <= np.iinfo(np.int8).max:
        return np.int8
    return np.int16 if n <= np.iinfo(np.int16).max else np.int64


def _by_sensor(sensor, n_sensors):
    """Stable order of the rows by sensor (time order within a sensor): a radix sort on small
    codes (8- or 16-bit codes sorted as they are, no copy)."""
    sensor = np.asarray(sensor)
    small = sensor.dtype.kind in "iu" and sensor.dtype.itemsize <= np.dtype(_key_type(n_sensors)).itemsize
    return np.argsort(sensor if small else sensor.astype(_key_type(n_sensors)), kind="stable")


def toggle_repeats_vectorised(sensor, on, n_sensors):
    """:func:`toggle_repeats` with numpy (used while numba is not loaded, as
    :func:`beam_pass_ends_vectorised`): per sensor, ``on`` equal to its previous edge's (off before the first)."""
    on = np.asarray(on, np.bool_)
    m = on.shape[0]
    same = np.zeros(m, dtype=np.bool_)
    if m == 0:
        return same
    order = _by_sensor(sensor, n_sensors)
    s_, o_ = np.asarray(sensor)[order], on[order]
    prev = np.zeros(m, dtype=np.bool_)
    prev[1:] = o_[:-1]
    prev[np.flatnonzero(s_[1:] != s_[:-1]) + 1] = False
    same[order] = o_ == prev
    return same


def _debounce_sorted(s_, o_, ts, chatter, min_on, eps):
    """The debounce of :func:`debounce_masks_vectorised` on edges already in sensor order
    (``s_`` sensor, ``o_`` on, ``ts`` time; time order within a sensor): chatter marks each
    (off, on) pair of neighbours of a sensor within its window; the minimum on-time rule marks
    each (on, off) pair of neighbours among the edges chatter left, sooner than ``min_on``.
    Every neighbour pair is tested at once with boolean masks over contiguous arrays (the gaps
    by one subtraction, for both rules); a rule shared by every sensor is one number. The
    neighbours among the edges chatter left are not gathered: they are the neighbours that are
    both left and, across each run of chatter pairs (adjacent pairs ``(i, i + 1), (i + 2, i + 3),
    ...``), the edge before the run and the edge after it. Returns the positions (in the sensor
    order) of the edges each rule marks, in no particular order."""
    m = o_.shape[0]
    none = np.empty(0, dtype=np.int64)
    chatter = np.asarray(chatter, np.float64)
    min_on = np.asarray(min_on, np.float64)
    use_chatter, use_min_on = bool((chatter > 0).any()), bool((min_on > 0).any())
    if m < 2 or not (use_chatter or use_min_on):
        return none, none
    cs = ss = first = none  # first: the first edge of each chatter pair
    same = s_[1:] == s_[:-1]  # neighbours of one sensor
    gap = np.subtract(ts[1:], ts[:-1])  # the gap of every pair of neighbours (k, k + 1)
    if use_chatter:  # (off, on) neighbours within the window
        w = _rule_of_pairs(chatter, s_)
        pair = same & o_[1:]
        pair &= ~o_[:-1]
        pair &= gap <= w + eps
        if not np.isscalar(w):
            pair &= w > 0
        first = np.flatnonzero(pair)  # pairs of neighbours never share an edge
        cs = np.concatenate([first, first + 1])
    if use_min_on:  # (on, off) neighbours among the edges chatter left
        w = _rule_of_pairs(min_on, s_)
        pair = same & o_[:-1]
        pair &= ~o_[1:]
        pair &= gap < w - eps
        if not np.isscalar(w):
            pair &= w > 0
        if first.size:  # neighbours both left
            gone = np.zeros(m, dtype=np.bool_)
            gone[first] = True
            gone[first + 1] = True
            pair &= ~gone[:-1]
            pair &= ~gone[1:]
        p = np.flatnonzero(pair)
        q = p + 1
        if first.size:  # across each run of chatter pairs: the edge before it and the edge after it
            joined = first[1:] == first[:-1] + 2  # the next pair starts right after this one
            a = first[np.r_[True, ~joined]] - 1
            b = first[np.r_[~joined, True]] + 2
            keep = (a >= 0) & (b < m)
            a, b = a[keep], b[keep]
            wb = w if np.isscalar(w) else min_on[s_[b]]
            x = (s_[a] == s_[b]) & o_[a] & ~o_[b] & (ts[b] - ts[a] < wb - eps)
            if not np.isscalar(wb):
                x &= wb > 0
            p, q = np.concatenate([p, a[x]]), np.concatenate([q, b[x]])
        ss = np.concatenate([p, q])
    return cs, ss


def _rule_of_pairs(per_sensor, s_):
    """A rule's value for each pair of neighbours ``(k, k + 1)`` in sensor order (the sensor of
    ``k + 1``), or one number when every sensor has the same."""
    if (per_sensor == per_sensor[0]).all():
        return float(per_sensor[0])
    return per_sensor[s_[1:]]


def debounce_masks_vectorised(sensor, on, t, chatter, min_on, n_sensors, eps):
    """:func:`debounce_masks` with numpy (used while numba is not loaded): chatter marks each
    (off, on) pair of neighbours in a sensor's sequence within its window; the minimum on-time
    rule marks each (on, off) pair of neighbours among the edges chatter left, sooner than
    ``min_on`` (the marks do not cascade, as in the kernel)."""
    sensor = np.asarray(sensor)
    on = np.asarray(on, np.bool_)
    t = np.asarray(t, np.float64)
    m = on.shape[0]
    chat = np.zeros(m, dtype=np.bool_)
    short = np.zeros(m, dtype=np.bool_)
    if m < 2:
        return chat, short
    order = _by_sensor(sensor, n_sensors)
    cs, ss = _debounce_sorted(sensor[order], on[order], t[order], chatter, min_on, eps)
    chat[order[cs]] = True
    short[order[ss]] = True
    return chat, short


def toggle_masks_vectorised(sensor, on, t, chatter, min_on, n_sensors, eps, *, step: int = 1 << 16):
    """:func:`toggle_repeats_vectorised` and then :func:`debounce_masks_vectorised` on the edges
    that are not repeats, in one sort by sensor: returns ``(same, chat, short)`` masks over all
    the edges (``chat`` and ``short`` false on the repeats). The edges a debounce sees are the
    non-repeats, still in sensor order after the sort (a stable subsequence), so one sort and
    one gather of the times serve both rules; equal to the two functions in turn (tests). The
    debounce runs on slices of whole sensors of at least ``step`` edges (:func:`_sensor_slices`:
    each sensor's neighbours are in its slice), so its temporaries are small and reused."""
    sensor = np.asarray(sensor)
    on = np.asarray(on, np.bool_)
    m = on.shape[0]
    same = np.zeros(m, dtype=np.bool_)
    chat = np.zeros(m, dtype=np.bool_)
    short = np.zeros(m, dtype=np.bool_)
    if m == 0:
        return same, chat, short
    order = _by_sensor(sensor, n_sensors)
    s_ = sensor[order].astype(_key_type(n_sensors))
    o_ = on[order]
    rep = np.empty(m, dtype=np.bool_)
    rep[0] = not o_[0]  # each sensor starts off: an off edge first is a repeat
    np.equal(o_[1:], o_[:-1], out=rep[1:])
    starts = np.flatnonzero(s_[1:] != s_[:-1]) + 1
    rep[starts] = ~o_[starts]
    repeated = np.flatnonzero(rep)
    same[order[repeated]] = True
    at = order
    if repeated.size:  # the debounce sees the other edges (still in sensor order)
        keep = np.flatnonzero(~rep)
        at, s_, o_ = order[keep], s_[keep], o_[keep]
    t = np.asarray(t, np.float64)
    for lo, hi in _sensor_slices(s_, step):  # whole sensors at a time: the same neighbours, small temporaries
        cs, ss = _debounce_sorted(s_[lo:hi], o_[lo:hi], t[at[lo:hi]], chatter, min_on, eps)
        chat[at[lo + cs]] = True
        short[at[lo + ss]] = True
    return same, chat, short


def _sensor_slices(s_: np.ndarray, step: int) -> list[tuple[int, int]]:
    """Cuts of edges in sensor order (``s_``) into slices of whole sensors, each at least
    ``step`` edges (but the last): a sensor's neighbours are all in its slice."""
    m = s_.shape[0]
    if m <= step:
        return [(0, m)]
    starts = np.flatnonzero(s_[1:] != s_[:-1]) + 1  # where each sensor after the first starts
    cuts, lo = [], 0
    for k in starts.tolist():
        if k - lo >= step:
            cuts.append((lo, k))
            lo = k
    cuts.append((lo, m))
    return cuts


@kernel
def toggle_repeats(sensor, on, n_sensors):
    """Edges of a toggle log in time order (``sensor`` index, ``on``) that do not change their
    sensor's state (every sensor starts off): ``on`` equal to the sensor's previous edge.
    The reference is the polars window expression in :func:`onebit.readers.motion.toggle_edges`
    (``shift(1).over("sensor")``)."""
    m = sensor.shape[0]
    same = np.zeros(m, dtype=np.bool_)
    state = np.zeros(n_sensors, dtype=np.bool_)
    for k in range(m):
        s = sensor[k]
        same[k] = on[k] == state[s]
        state[s] = on[k]
    return same
