"""Lagged decoding: FindingHuMo's live requirement, one block of slots at a time.

The paper (section III) asks that each user's state ``q_i(t)`` be computed by ``t + D'T``,
``D' << D``: the Adaptive-HMM decodes windows of ``d_max`` slots as the data stream in, keeps
the first ``tau`` slots of each, and CPDA disambiguates the output of the last ``C`` windows
(Algorithm 1). It gives no value of ``D'``. The batch run of this package (``decoding =
"batch"``) cannot be that: it learns the EATG from the whole log (eqs. 1, 2 over every slot),
and re-decodes meetings and runs CPDA over the whole run, so a slot's output changes when
later slots arrive. ``decoding = "lagged"`` is the live algorithm, run the same way by ``onebit
run`` and ``onebit follow``:

* the **EATG is known beforehand**: ``eatg = "layout"`` or ``"file"`` (a table learned from a
  training log), never learned from the log being decoded;
* the **window decoder** (:class:`~onebit.models.graph_hmm.adaptive.WindowDecoder`) decodes
  a window once its ``d_max`` slots have arrived; slot ``k`` of its output is final once the
  next window starts more than ``resume`` (10) slots after ``k`` (a user leaving and coming
  back through a door within that time is the same user; the slots between are filled);
* the output is **committed in blocks** of ``tau`` slots (the slots one window accepts)
  ``[b0, b1)``, each once the decoder's final slots reach ``b1 + ahead``, ``ahead = D' - d_max
  - resume``; so a block is decided no later than when slot ``b1 - 1 + D'`` has arrived. The
  block's post-processing works on a segment: the committed output of the ``lag_lookback``
  slots before ``b0`` (at least CPDA's "last C windows", ``C d_max``; held as they were
  published), the block, and the
  look-ahead up to ``b1 + ahead`` -- kept from the previous block's post-processing where it
  had it, the decoder's output relabelled for the rest. On the segment: the joint
  re-decoding of the meetings that *end* in the block, seen whole with the slots after them
  (:func:`~onebit.models.graph_hmm.joint.redecode_meetings`, ``decide``; the slots of a meeting
  already committed stay as they were, an exchange of tails relabels the rest), CPDA on the events
  that *end* in the block (:func:`~onebit.trackers.findinghumo.cpda.cpda`, ``decide``), the
  block's slots committed, the rest kept as the next look-ahead. A switch or an exchange of
  tails relabels the users from its slot on: the decoder's later rows are relabelled by the
  permutation ``perm`` (output label -> decoder user) that the switches compose;
* the **user cap** (``targets``) runs slot by slot on the committed blocks
  (:class:`~onebit.models.graph_hmm.decoding.UserCap`) -- always, also while fewer users than
  the cap have been seen (the batch run skips it then, which needs the whole run's count).

Every step reads only slots that are final when its block is committed, and the blocks are
cut by slot numbers, never by when the slots arrived; so feeding the slots in any pieces
(``onebit follow``, poll by poll) and feeding them all at once (``onebit run``) commit the same
blocks with the same paths -- tested on random cuts. The cost is linear in the run: each
block's post-processing works on a segment of ``lag_lookback + tau + ahead`` slots.

Delay (slots): slot ``t`` of block ``[b0, b1)`` is committed by the time slot ``b1 - 1 + D'``
has arrived, at most ``tau - 1 + D'`` slots after ``t``; a slot's activity is final about 1.5
slots after it (the mid-time sampling of the next slot) plus the readers' settle time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import polars as pl

from onebit.core.frames import outside_silence, silent_stretches
from onebit.core.site import Site
from onebit.models.graph_hmm.adaptive import RESUME_SLOTS, WindowDecoder
from onebit.models.graph_hmm.decoding import (
    HmmConfig,
    UserCap,
    decoder_params,
    mid_activity,
    signature_indices,
    slot_activity,
    tracks_table,
    user_bound,
)
from onebit.models.graph_hmm.eatg import Eatg
from onebit.models.graph_hmm.joint import JointSpaces, redecode_meetings
from onebit.trackers.findinghumo.cpda import CpdaResult, cpda


class LaggedDecoder:
    """The lagged decoding of one tracker (module docstring): slots in (:meth:`extend`),
    committed blocks out (:meth:`commit`). Its state is its own, passed explicitly."""

    def __init__(self, mode: str, site: Site, cfg: HmmConfig, eatg: Eatg, *, cpda_windows: int | None):
        g = site.sensor_graph
        self.cfg = cfg
        self.eatg = eatg
        self.nodes = g.nodes
        self.dec = WindowDecoder(
            eatg, len(g.nodes), signatures=signature_indices(g, eatg), params=decoder_params(site, cfg, mode)
        )
        self.cpda_windows = cpda_windows  # C, or None: no CPDA (hmm1 / hmm2)
        fh = cpda_windows is not None
        self.joint_before = cfg.joint == "before-cpda" or (cfg.joint == "after-cpda" and not fh)
        self.joint_after = fh and cfg.joint == "after-cpda"
        self.spaces = JointSpaces(eatg, cfg.joint_hops) if (self.joint_before or self.joint_after) else None
        self.block = cfg.tau
        self.back = cfg.lag_lookback
        self.ahead = cfg.decision_lag - cfg.d_max - RESUME_SLOTS
        self.feature = np.isin(np.asarray(g.nodes), list(g.entries) + list(g.exits))
        cap = user_bound(site, cfg)
        self.cap = UserCap(cap, eatg.hops) if cap > 0 else None
        self.committed = 0  # slots [0, committed) are final
        self.out = np.zeros((0, 0), dtype=np.int64)  # (labels, capacity) committed paths before the cap
        self.buf = np.zeros((0, 0), dtype=np.int64)  # post-processed look-ahead [committed, buf_hi)
        self.buf_hi = 0
        self.perm: list[int] = []  # output label -> decoder user (for slots >= buf_hi)
        self.switches: list[tuple[int, int, tuple[int, ...], tuple[int, ...]]] = []
        self.decisions: list[dict] = []
        self.joint_log: list[dict] = []
        self.passes = 0  # the most CPDA passes one block took

    def extend(self, active: np.ndarray) -> None:
        """Append final slots ``active`` (L, N)."""
        self.dec.extend(active)

    def commit(self, *, final: bool = False) -> list[tuple[int, np.ndarray]]:
        """Decode what arrived and commit every block that is final: ``[(b0, paths (U, b1 - b0))]``
        after the user cap (``final``: the log ended, every slot left is committed)."""
        self.dec.advance(final=final)
        n, ready = self.dec.n_slots, self.dec.final_slots
        blocks = []
        while self.committed < n:
            b0 = self.committed
            b1 = min(b0 + self.block, n)
            hi = min(b1 + self.ahead, n)
            if not final and b1 + self.ahead > ready:
                break
            paths = self._block(b0, b1, hi)
            if self.cap is not None:
                paths = self.cap.step(paths, self.dec.activity(b0, b1))
            blocks.append((b0, paths))
            self.committed = b1
        return blocks

    def _labels(self) -> int:
        """Give the decoder's new users output labels; the number of labels."""
        k = len(self.dec.rows)
        self.perm += list(range(len(self.perm), k))
        if self.out.shape[0] < k or self.out.shape[1] < self.dec.n_slots:
            out = np.full((k, max(self.dec.n_slots, 2 * self.out.shape[1], 64)), -1, dtype=np.int64)
            out[: self.out.shape[0], : self.out.shape[1]] = self.out
            self.out = out
        return k

    def _block(self, b0: int, b1: int, hi: int) -> np.ndarray:
        k = self._labels()
        lo = max(0, b0 - self.back)
        seg = np.full((k, hi - lo), -1, dtype=np.int64)
        seg[:, : b0 - lo] = self.out[:k, lo:b0]
        kb, nb = self.buf.shape[0], min(self.buf_hi, hi) - b0
        if nb > 0:
            seg[:kb, b0 - lo : b0 - lo + nb] = self.buf[:, :nb]
        start = max(self.buf_hi, b0)
        seg[:, start - lo :] = self.dec.paths(start, hi)[self.perm]
        active = self.dec.activity(lo, hi)
        owner = np.arange(k)  # tail of each label at the segment's end: that of label owner[u] before
        r0, r1 = b0 - lo, b1 - lo
        cfg = self.cfg
        if self.joint_before:
            seg = self._joint(seg, active, owner, lo, r0, r1)
        if self.cpda_windows is not None:
            cp = cpda(
                seg,
                self.eatg.a2,
                horizon=self.cpda_windows * cfg.d_max,
                feature=self.feature,
                hops=self.eatg.hops,
                max_passes=cfg.cpda_passes,
                decide=(r0, r1),
            )
            seg = cp.paths
            self.passes = max(self.passes, cp.passes)
            for b, node, users, paired in cp.switches:
                owner[np.asarray(users)] = owner[np.asarray(paired)]
                self.switches.append((b + lo, node, users, paired))
            for d in cp.decisions:
                self.decisions.append({**d, "slot": d["slot"] + lo})
        if self.joint_after:
            seg = self._joint(seg, active, owner, lo, r0, r1)
        self.perm = [self.perm[int(o)] for o in owner]
        self.out[:k, b0:b1] = seg[:, r0:r1]
        self.buf, self.buf_hi = seg[:, r1:].copy(), hi
        return seg[:, r0:r1]

    def _joint(self, seg, active, owner, lo, r0, r1):
        cfg = self.cfg
        seg, log = redecode_meetings(
            seg,
            active,
            self.eatg,
            p_hit=cfg.p_hit,
            p_false=cfg.p_false,
            pad=cfg.joint_pad,
            decide=(r0, r1),
            spaces=self.spaces,
        )
        for rec in log:
            if rec["exchanged"]:
                u, v = rec["users"]
                owner[[u, v]] = owner[[v, u]]
            self.joint_log.append({**rec, "slot": rec["slot"] + lo, "end": rec["end"] + lo})
        return seg

    def cpda_result(self) -> CpdaResult:
        """The CPDA switches and decisions of every block (slots of the run; ``passes``: the most
        one block took)."""
        return CpdaResult(self.out[:, : self.committed], list(self.switches), self.passes, list(self.decisions))


def lagged_paths(
    mode: str, active: np.ndarray, site: Site, cfg: HmmConfig, eatg: Eatg, *, cpda_windows: int | None
) -> tuple[np.ndarray, LaggedDecoder]:
    """The whole run through :class:`LaggedDecoder` at once: ``(paths (U, D) after the cap, the decoder)``."""
    lag = LaggedDecoder(mode, site, cfg, eatg, cpda_windows=cpda_windows)
    lag.extend(active)
    blocks = lag.commit(final=True)
    return stack_blocks(blocks, active.shape[0]), lag


def stack_blocks(blocks: list[tuple[int, np.ndarray]], n_slots: int) -> np.ndarray:
    """Committed blocks -> one ``(U, n_slots)`` array (users that appear later: -1 before)."""
    k = max((p.shape[0] for _, p in blocks), default=0)
    out = np.full((k, n_slots), -1, dtype=np.int64)
    for b0, p in blocks:
        out[: p.shape[0], b0 : b0 + p.shape[1]] = p
    return out


# --------------------------------------------------------------------------- online (onebit follow)


@dataclass
class OnlineHmm:
    """One HMM tracker followed live: its :class:`LaggedDecoder`, the slot grid's origin, the
    slots fed, and the committed rows not yet published (held until a settled event at or
    after their time decides whether they lie in a silent stretch, as the batch run drops them).

    Each call works on the recent edges only -- those at or after a cut a few slots before
    the first slot it still needs, with each sensor's last two edges before the cut
    (``before``, kept up to date as the cut moves on: its state at the cut, and for the count
    of sensors on that decides silent stretches, the ON of a last OFF) -- so a poll costs
    the new slots, not the run."""

    name: str
    config: HmmConfig
    site: Site
    lag: LaggedDecoder
    t0: float | None = None
    fed: int = 0
    pending: pl.DataFrame | None = None
    cut_row: int = 0  # rows of the (sorted) motion table before the cut
    before: pl.DataFrame | None = None  # each sensor's last two edges before the cut


def start(name: str, mode: str, site: Site, config: HmmConfig, eatg: Eatg, *, cpda_windows: int | None) -> OnlineHmm:
    if config.decoding != "lagged":
        raise ValueError(f"{name}: online decoding needs decoding = 'lagged' (is {config.decoding!r})")
    return OnlineHmm(name, config, site, LaggedDecoder(mode, site, config, eatg, cpda_windows=cpda_windows))


def final_slot_count(t0: float, period: float, settled_until: float, grid_slots: int) -> int:
    """Slots of the grid whose activity no later edge changes, when every edge up to
    ``settled_until`` is known: slot ``k`` is final once the log passed the mid time of slot
    ``k + 1`` (an on-period shorter than a slot is placed by its own mid time, which needs its
    end), and the last slot of the known grid is not (an open on-period is cut there)."""
    by_time = int(np.floor((settled_until - t0) / period - 1.5)) + 1
    return max(0, min(by_time, grid_slots - 1))


def advance(state: OnlineHmm, motion: pl.DataFrame, *, settled_until: float, final: bool) -> pl.DataFrame:
    """Feed the slots final with the settled ``motion`` edges (all edges when ``final``), commit
    the blocks that are decided and return the rows to publish now (the TRACKS rows at or
    before the last settled edge, outside silent stretches; every row left when ``final``).

    ``motion``: the MOTION table read so far, sorted by ``t`` (the reader's order); only its
    rows after the cut are looked at."""
    cfg, site = state.config, state.site
    nodes = site.sensor_graph.nodes
    period = cfg.period
    t = motion["t"]
    end = motion.height if final else int(t.search_sorted(settled_until, side="right"))
    recent = motion.slice(state.cut_row, end - state.cut_row).filter(pl.col("sensor").is_in(list(nodes)))
    if state.t0 is None:
        if recent.height == 0:
            return _empty_tracks(state)
        state.t0 = math.floor(float(recent["t"].min()) / period) * period  # the slot grid of motion_frames
    t0 = state.t0
    window = recent if state.before is None else pl.concat([state.before, recent.select(state.before.columns)])
    if window.height == 0:
        return _empty_tracks(state)
    last = float(window["t"].max())
    grid = max(int(math.floor((last - t0) / period)) + 1, 1)  # slot_grid's count
    n = grid if final else final_slot_count(t0, period, settled_until, grid)
    if n > state.fed:
        if cfg.sampling == "mid":
            act = mid_activity(window, nodes, period, t0=t0, grid_slots=grid, slot0=state.fed, n_slots=n - state.fed)
        else:  # "any": the frames of the whole table (motion_frames' own grid)
            act = slot_activity(motion.slice(0, end), nodes, period, "any")[0][state.fed : n]
        state.lag.extend(act)
        state.fed = n
    parts = [state.pending] if state.pending is not None else []
    for b0, paths in state.lag.commit(final=final):
        parts.append(tracks_table(state.name, paths, nodes, site, t0, period, slot0=b0))
    rows = pl.concat(parts) if parts else _empty_tracks(state)
    newest = float(recent["t"].max()) if recent.height else -math.inf
    last_edge = max(
        newest, float(state.before["t"].max()) if state.before is not None and state.before.height else -math.inf
    )
    ready = rows if final else rows.filter(pl.col("t") <= last_edge)
    state.pending = None if final else rows.filter(pl.col("t") > last_edge)
    published = outside_silence(ready, silent_stretches([window], min_s=cfg.absent_after))
    # move the cut on: a few slots before the first slot still needed (the next slots to feed,
    # the rows still pending), never back; the edges passed go into ``before``
    need = state.lag.committed  # <= fed: the rows of the blocks still to commit need their silence too
    if state.pending is not None and state.pending.height:
        need = min(need, int(math.floor((float(state.pending["t"].min()) - t0) / period)))
    cut = t0 + (need - 3) * period
    cut_row = int(t.search_sorted(cut, side="left"))
    if cut_row > state.cut_row and not final:
        passed = motion.slice(state.cut_row, cut_row - state.cut_row).filter(pl.col("sensor").is_in(list(nodes)))
        both = passed if state.before is None else pl.concat([state.before, passed.select(state.before.columns)])
        # per sensor its last two edges: the last gives its state at the cut; with an OFF last,
        # the ON before it keeps the count of sensors on (silent_stretches' +-1 sum) right
        state.before = both.group_by("sensor", maintain_order=True).tail(2).select(motion.columns)
        state.before = state.before.sort("t", maintain_order=True)
        state.cut_row = cut_row
    return published


def _empty_tracks(state: OnlineHmm) -> pl.DataFrame:
    return tracks_table(state.name, np.zeros((0, 0), np.int64), state.site.sensor_graph.nodes, state.site, 0.0, 1.0)
