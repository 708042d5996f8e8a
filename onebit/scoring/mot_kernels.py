"""Compiled (numba) frame loops of the MOT scorer (:mod:`onebit.scoring.mot`).

Frames are flat arrays: frame ``f`` has the objects ``oids[o_ptr[f]:o_ptr[f+1]]``, the
hypotheses ``hids[h_ptr[f]:h_ptr[f+1]]`` and the row-major (objects x hypotheses) matrix
``w[d_ptr[f]:d_ptr[f+1]]``.

Both loops need a per-frame assignment. Frames of people-counting trackers are small (a few
objects, a few tracks), so the assignment is found by enumerating every matching of the
frame's admissible pairs (:func:`best_matching`). A solver (``motmetrics``' ``lapjv``,
TrackEval's ``scipy``) returns *one* optimum; when the optimum is not unique (a tie, or two
matchings within ``TIE`` of each other) which one it returns is the solver's business, so the
kernel stops at that frame and hands it to the very solver the library calls
(:mod:`onebit.scoring.mot`), then resumes. Frames too large to enumerate are handed over too.
The result is the library's, frame for frame, by construction; the plain-Python versions of
these kernels (``.py_func``) are their test oracles, and the libraries are the oracles of both
(``tests/scoring/test_mot_fast.py``).
"""

from __future__ import annotations

import numpy as np

from onebit.core.compiled import kernel

#: Two matchings whose objective differs by at most this are a tie (handed to the solver).
TIE = 1e-9
#: Frames whose admissible pairs would need more matchings than this are handed to the solver.
MAX_MATCHINGS = 5000

#: :func:`best_matching` status codes.
UNIQUE, AMBIGUOUS, TOO_LARGE = 0, 1, 2


@kernel
def _matchings_bound(ok, rows, k, n_cols):
    """A bound of the matchings :func:`best_matching` enumerates: the product over its ``k``
    rows of (1 + admissible columns)."""
    bound = 1.0
    for r in range(k):
        c = 1
        for j in range(n_cols):
            if ok[rows[r] * n_cols + j]:
                c += 1
        bound *= c
    return bound


@kernel
def best_matching(w, ok, n_rows, n_cols, by_count, choice):
    """The best matching of a small (n_rows x n_cols) problem, by enumeration.

    ``w`` (row-major) weights, ``ok`` admissible pairs. Objective: with ``by_count`` the most
    pairs, then the least total weight (``motmetrics``: inadmissible pairs cost more than any
    admissible assignment); else the largest total weight (TrackEval's HOTA matching, whose
    pairs of zero weight match nothing). Writes ``choice[i]`` (column of row ``i`` or -1) and
    returns ``UNIQUE``, ``AMBIGUOUS`` (another matching within :data:`TIE`) or ``TOO_LARGE``.

    Every matching is visited once (depth-first over rows, each row taking no column or an
    admissible unused one), so the optimum is unique iff no other visited matching comes within
    ``TIE`` of it.
    """
    rows = np.empty(n_rows, np.int64)
    k = 0
    for i in range(n_rows):
        choice[i] = -1
        for j in range(n_cols):
            if ok[i * n_cols + j]:
                rows[k] = i
                k += 1
                break
    if k == 0:
        return UNIQUE
    if _matchings_bound(ok, rows, k, n_cols) > MAX_MATCHINGS:
        return TOO_LARGE
    cur = np.full(k, -2, np.int64)  # -2: not started; -1: no column; else the column
    used = np.zeros(n_cols, np.bool_)
    best = np.full(k, -1, np.int64)
    best_cnt, best_val, second_val = -1, 0.0, 0.0
    have_second = False
    level = 0
    while level >= 0:
        i = rows[level]
        c = cur[level]
        if c >= 0:
            used[c] = False
        c += 1
        while c < n_cols and (c >= 0 and (used[c] or not ok[i * n_cols + c])):
            c += 1
        if c >= n_cols:
            cur[level] = -2
            level -= 1
            continue
        cur[level] = c
        if c >= 0:
            used[c] = True
        if level < k - 1:
            level += 1
            continue
        cnt = 0
        val = 0.0
        for r in range(k):
            if cur[r] >= 0:
                cnt += 1
                val += w[rows[r] * n_cols + cur[r]]
        if not by_count:
            val = -val  # maximise the weight: minimise its negative
            cnt = 0
        if cnt > best_cnt or (cnt == best_cnt and val < best_val):
            if cnt == best_cnt:
                second_val, have_second = best_val, True
            else:
                have_second = False
            best_cnt, best_val = cnt, val
            for r in range(k):
                best[r] = cur[r]
        elif cnt == best_cnt and (not have_second or val < second_val):
            second_val, have_second = val, True
    for r in range(k):
        choice[rows[r]] = best[r]
    if have_second and second_val - best_val <= TIE * (1.0 + abs(best_val)):
        return AMBIGUOUS
    return UNIQUE


@kernel
def _continuing_pairs(oids, hids, d, gate, last, omask, hmask, first):
    """Step (1) of :func:`clear_pass` for one frame (its objects ``oids``, hypotheses ``hids``,
    distances ``d`` row-major): each object, in id order, keeps its last matched hypothesis
    when present, unclaimed and within the gate. Marks both in ``omask``/``hmask``, writes the
    distances to ``first``; returns how many."""
    no, nh = oids.shape[0], hids.shape[0]
    n1 = 0
    for i in range(no):
        hp = last[oids[i]]
        if hp < 0:
            continue
        for j in range(nh):
            if hids[j] == hp and not hmask[j]:
                x = d[i * nh + j]
                if x <= gate:  # False for NaN
                    omask[i] = True
                    hmask[j] = True
                    first[n1] = x
                    n1 += 1
                break
    return n1


@kernel
def clear_pass(f0, o_ptr, oids, h_ptr, hids, d_ptr, d, gate, last, counts, events):
    """CLEAR MOT (``motmetrics.MOTAccumulator.update``) over frames ``f0, f0+1, ...``.

    Per frame: (1) each object, in id order, whose last matched hypothesis ``last[o]`` is present
    and unclaimed keeps it when their distance is within the gate (a match); (2) the remaining
    objects and hypotheses are matched by the most pairs within the gate, then the least total
    distance (:func:`best_matching`); a pair whose object was last matched to another hypothesis
    is a switch; ``last[o]`` becomes its hypothesis; (3) unmatched objects are misses, unmatched
    hypotheses false positives. Accumulates ``counts = [matches, switches, misses, false
    positives, events]`` and writes each event's distance to ``events`` in motmetrics' order
    (matches of (1), pairs of (2) by object, then 0 for each miss and false positive: its MOTP
    is the sum of that column), updates ``last``. Returns the first frame it cannot decide
    alone (a tie or too large, untouched) or the frame count.
    """
    n_frames = len(o_ptr) - 1
    choice = np.empty(64, np.int64)
    for f in range(f0, n_frames):
        oa, ob = o_ptr[f], o_ptr[f + 1]
        ha, hb = h_ptr[f], h_ptr[f + 1]
        no, nh = ob - oa, hb - ha
        e = counts[4]
        if no == 0 or nh == 0:
            for _ in range(no + nh):
                events[e] = 0.0
                e += 1
            counts[2] += no
            counts[3] += nh
            counts[4] = e
            continue
        if no > 64:
            return f
        da = d_ptr[f]
        omask = np.zeros(no, np.bool_)
        hmask = np.zeros(nh, np.bool_)
        first = np.empty(no, np.float64)
        n1 = _continuing_pairs(oids[oa:ob], hids[ha:hb], d[da : da + no * nh], gate, last, omask, hmask, first)
        ok = np.zeros(no * nh, np.bool_)
        for i in range(no):
            if omask[i]:
                continue
            for j in range(nh):
                if not hmask[j] and d[da + i * nh + j] <= gate:
                    ok[i * nh + j] = True
        status = best_matching(d[da : da + no * nh], ok, no, nh, True, choice)
        if status != UNIQUE:
            return f
        for k in range(n1):
            events[e] = first[k]
            e += 1
        matches = n1
        switches = 0
        for i in range(no):
            j = choice[i]
            if j < 0:
                continue
            o = oids[oa + i]
            h = hids[ha + j]
            if last[o] >= 0 and last[o] != h:
                switches += 1
            else:
                matches += 1
            events[e] = d[da + i * nh + j]
            e += 1
            last[o] = h
            omask[i] = True
            hmask[j] = True
        done = matches + switches  # objects matched in (1) or (2)
        for _ in range(no - done + nh - done):
            events[e] = 0.0
            e += 1
        counts[0] += matches
        counts[1] += switches
        counts[2] += no - done
        counts[3] += nh - done
        counts[4] = e
    return n_frames


@kernel
def hota_matches(o_ptr, h_ptr, d_ptr, score, out_pairs, handover):
    """TrackEval's HOTA matching of every frame: the assignment of largest total ``score``
    (alignment x similarity), its pairs of positive score written as flat indices into
    ``score`` in ``out_pairs``; returns ``(n_pairs, n_handed)``, the frames that are ties or too
    large listed in ``handover`` for the solver."""
    n_frames = len(o_ptr) - 1
    choice = np.empty(64, np.int64)
    n = 0
    m = 0
    for f in range(n_frames):
        no = o_ptr[f + 1] - o_ptr[f]
        nh = h_ptr[f + 1] - h_ptr[f]
        if no == 0 or nh == 0:
            continue
        if no > 64:
            handover[m] = f
            m += 1
            continue
        da = d_ptr[f]
        w = score[da : da + no * nh]
        ok = w > 0.0
        status = best_matching(w, ok, no, nh, False, choice)
        if status != UNIQUE:
            handover[m] = f
            m += 1
            continue
        for i in range(no):
            if choice[i] >= 0:
                out_pairs[n] = da + i * nh + choice[i]
                n += 1
    return n, m
