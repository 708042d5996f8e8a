"""The plain versions of shipped steps, each the test oracle of one (``tests/``) and the
baseline of its benchmark (``benchmarks/``); nothing in the package calls them.

=====================================  =========================================================
oracle                                 the shipped step it checks
=====================================  =========================================================
:func:`pir_refractory_reference`       :func:`onebit.datasets.kernels.pir_refractory`
:func:`fill_images_reference`          :func:`onebit.viz.istate.fill_images`
:func:`region_scores_reference`        :func:`onebit.scoring.crossings.region_scores`
:func:`pair_meeting_reference`         :func:`onebit.trackers.findinghumo.cpda.pair_meeting`
:func:`scan_clusters_direct`           :func:`onebit.trackers.clustertrack.algorithm.scan_clusters`
:func:`motion_frames_reference`        :func:`onebit.core.frames.motion_frames`
:func:`istate_filter_reference`        ``onebit.trackers.istate.stage._filter`` (the stage loop)
:func:`communicate_bruteforce`        :func:`onebit.trackers.istate.core.communicate`
:func:`posteriors_bruteforce`         :func:`onebit.trackers.residents.known.posteriors`
=====================================  =========================================================
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from itertools import product

import numpy as np
import polars as pl
import shapely
from scipy.special import logsumexp

from onebit.core.frames import slot_grid
from onebit.core.region_graph import RegionGraph
from onebit.core.tables import FRAMES, SCORES, conform
from onebit.scoring.crossings import truth_regions
from onebit.trackers.findinghumo.cpda import _jumps, _pairings, junction_score
from onebit.trackers.istate.core import IState, PairMemo, clean_up, constrain, info_state_update, permutations
from onebit.trackers.istate.stage import IStateConfig, Stages, _point_summary
from onebit.trackers.residents.known import Chains
from onebit.viz import colors
from onebit.viz.istate import FILL_ALPHA, FillRaster, _png, element_color


def pir_refractory_reference(col, start, end, times, refr, dt):
    """The plain loop of :func:`onebit.datasets.kernels.pir_refractory` (its test oracle)."""
    K = times.shape[0]
    keep, keep_s = np.ones(col.size, dtype=bool), start.copy()
    blind = np.full(refr.shape[0], -np.inf)
    for k in range(col.size):  # sequential: a period's fate depends on the last one kept
        i = col[k]
        ready = int(math.ceil((blind[i] - times[0]) / dt - 1e-9)) if np.isfinite(blind[i]) else 0
        if end[k] <= ready:
            keep[k] = False
            continue
        keep_s[k] = max(start[k], ready)
        blind[i] = times[min(end[k], K - 1)] + refr[i]
    return keep, keep_s


def fill_images_reference(grid: np.ndarray, raster: FillRaster, *, background=colors.MAP_BACKGROUND) -> list[bytes]:
    """:func:`fill_images` blending every region into a float image pixel by pixel: the plain
    reference (and test oracle) of the label-table version."""
    E, _, K = grid.shape
    out = []
    bg = np.asarray(background[:3], np.float32)
    for s in range(K):  # one image per stage; the elements of a stage are few (cap M)
        rgb = np.empty((raster.height, raster.width, 3), np.float32)
        rgb[:] = bg
        for e in range(E):
            c = np.asarray(element_color(e)[:3], np.float32)
            for g in grid[e, :, s]:  # each region of the element on its own: nested ones show
                if g is None or g.is_empty:
                    continue
                m = raster.mask(g).astype(bool)
                rgb[m] = c * FILL_ALPHA + rgb[m] * (1 - FILL_ALPHA)
        out.append(_png(rgb.round().clip(0, 255).astype(np.uint8)))
    return out


def region_scores_reference(
    tracks: pl.DataFrame, truth: pl.DataFrame, mapping: dict[str, str], rg: RegionGraph, *, tracker: str
) -> pl.DataFrame:
    """:func:`region_scores` computed row by row (region names looked up per sample, a shapely
    distance for every sample): its plain reference and test oracle."""
    if not mapping or truth.height == 0 or tracks.height == 0:
        return pl.DataFrame(schema=SCORES)
    m = pl.DataFrame({"track": list(mapping), "target": list(mapping.values())})
    est = tracks.select("track", "t", est_region="region").join(m, on="track").sort("t")
    tru = truth_regions(truth.select("t", "target", "x", "y"), rg).drop_nulls("region").sort("t")
    j = tru.join_asof(est, on="t", by="target", strategy="backward", check_sortedness=False).drop_nulls("est_region")
    if j.height == 0:
        return pl.DataFrame(schema=SCORES)
    idx = rg.index
    e = np.array([idx[r] for r in j["est_region"].to_list()])
    g = np.array([idx[r] for r in j["region"].to_list()])
    hops = rg.hop_distance()[e, g]
    polys = np.asarray(rg.polygons, dtype=object)
    err = shapely.distance(polys[e], shapely.points(j["x"].to_numpy(), j["y"].to_numpy()))
    out = j.select("track", "target", "t").with_columns(
        tracker=pl.lit(tracker), error=pl.Series(err, dtype=pl.Float64), hop_error=pl.Series(hops, dtype=pl.Int64)
    )
    return conform(out, SCORES)


def pair_meeting_reference(
    paths: np.ndarray, users: np.ndarray, s0: int, c: int, log_a2: np.ndarray, hops: np.ndarray | None
) -> tuple[list[tuple[int, ...]], np.ndarray, np.ndarray]:
    """:func:`pair_meeting` the plain way, the test oracle: every joined path scored whole
    (``O(D)`` per pairing and slot), ``log P(sigma, b) = sum_u junction_score(path_u[:b] ++
    path_sigma(u)[b:])`` in absolute terms (``logp[0]`` is the HMM pairing's own)."""
    perms, logp, slot, rows = _pairings(paths, users, c)
    logp[0] = sum(junction_score(r, log_a2) for r in rows)
    for k, p in enumerate(perms[1:], start=1):  # m <= MAX_MEETING users, a few slots: tiny
        for b in range(c + 1, s0, -1):
            if _jumps(rows, p, b, hops):
                continue
            score = sum(junction_score(np.concatenate([rows[u][:b], rows[p[u]][b:]]), log_a2) for u in range(len(p)))
            if score > logp[k] + 1e-9:
                logp[k], slot[k] = score, b
    return perms, logp, slot


def scan_clusters_direct(order: np.ndarray, traj: np.ndarray, *, H: int, K: int, L: int, D0: float):
    """Algorithm 1's scan (steps 3-18) transcribed literally, per particle: one Python
    iteration per scanned candidate, the distance to every cluster head recomputed from the
    full trajectories ``D = (1/t) sum_l ||P[l] - CH[l]||``. Candidates are scanned in the given
    ``order`` (already sorted by cost).

    ``traj (n, t, d)``: full candidate trajectories. Returns ``(kept, label, n_scanned)``
    with ``kept`` candidate indices in scan order and their cluster ids.
    """
    heads: list[int] = []
    count: list[int] = []
    kept: list[int] = []
    label: list[int] = []
    scanned = 0
    for i in order[:L]:  # one candidate per iteration, as in the pseudo-code
        if len(kept) >= K:
            break
        scanned += 1
        if heads:
            d = [float(np.mean(np.sqrt(np.sum((traj[i] - traj[h]) ** 2, axis=-1)))) for h in heads]
            j = int(np.argmin(d))
            if d[j] < D0:
                if count[j] < H:
                    count[j] += 1
                    kept.append(int(i))
                    label.append(j)
                continue
        heads.append(int(i))
        count.append(1)
        kept.append(int(i))
        label.append(len(heads) - 1)
    return np.asarray(kept, dtype=np.int64), np.asarray(label, dtype=np.int64), scanned


def motion_frames_reference(
    motion: pl.DataFrame, sensors: Sequence[str], *, period: float, t0: float | None = None, t1: float | None = None
) -> pl.DataFrame:
    """:func:`motion_frames` by polars joins (a cross join of slots and sensors, an as-of join
    for the state, a join for the rising edges): its plain reference and test oracle."""
    sensors, ev, span = slot_grid(motion, sensors, period=period, t0=t0, t1=t1)  # the same slots, by construction
    if span is None:
        return pl.DataFrame(schema=FRAMES)
    t0, n = span
    grid = (
        pl.DataFrame({"slot": pl.arange(0, n, eager=True).cast(pl.Int64)})
        .join(pl.DataFrame({"sensor": sensors}, schema={"sensor": pl.String}), how="cross")
        .with_columns(t=pl.lit(t0) + pl.col("slot").cast(pl.Float64) * period)
    )
    ev = ev.with_columns(slot=((pl.col("t") - t0) / period).floor().cast(pl.Int64))
    fired = (
        ev.filter(pl.col("on") & (pl.col("slot") >= 0) & (pl.col("slot") < n))
        .group_by("sensor", "slot")
        .agg(fired=pl.lit(True))
    )
    state = grid.sort("t").join_asof(
        ev.select("t", "sensor", pl.col("on").alias("state")).sort("t"),
        on="t",
        by="sensor",
        strategy="backward",
        check_sortedness=False,  # both sides are sorted by t just above
    )
    out = (
        state.join(fired, on=["sensor", "slot"], how="left")
        .with_columns(pl.col("fired").fill_null(False), pl.col("state").fill_null(False))
        .with_columns(on=pl.col("state") | pl.col("fired"))
    )
    order = pl.DataFrame(
        {"sensor": sensors, "_k": list(range(len(sensors)))}, schema={"sensor": pl.String, "_k": pl.Int64}
    )
    out = out.join(order, on="sensor").sort(["slot", "_k"])
    return conform(out, FRAMES)


def istate_filter_reference(stages: Stages, config: IStateConfig) -> tuple[np.ndarray, list, np.ndarray, np.ndarray]:
    """:func:`onebit.trackers.istate.stage._filter` computing every stage (the plain loop; its test oracle): an I-state per stage."""
    times, n = stages.times, stages.n
    K = len(times)
    db, nb = stages.det_bounds, stages.neg_bounds
    eta = IState.initial(stages.free, n)
    cap = config.max_elements or None
    reg_rows, summ, track_xy = [], np.zeros((K, 4)), np.zeros((K, n, 2))
    prev = None
    memo = PairMemo()
    free_area = float(stages.free.area) or 1.0
    for k in range(K):
        rejected: list | None = [] if config.contradictions == "reject" else None
        eta = info_state_update(
            eta,
            stages.detections[db[k] : db[k + 1]],
            step=stages.step if k else 0.0,
            free_space=stages.free,
            shape=config.shape,
            max_elements=cap,
            negatives=stages.negatives[nb[k] : nb[k + 1]],
            substeps=config.substeps,
            memo=memo,
            rejected=rejected,
        )
        reg_rows.append(eta.regions.ravel())
        area = memo.recall(eta, stages.free, "total_area", IState.total_area)  # as the filter always did
        summ[k] = (eta.size, len(rejected or ()), area / free_area, area)
        track_xy[k] = prev = _point_summary(eta, prev, n)
    return np.arange(K, dtype=np.int64), reg_rows, summ, track_xy


def communicate_bruteforce(a: IState, b: IState, *, shape: str = "exact") -> IState:
    """The direct formula of section VI-B, ``O(Ea Eb n!)`` intersections: every element pair
    and every permutation, empty products dropped, then clean-up (reference for tests and
    the benchmark)."""
    Ea, Eb, n = a.size, b.size, a.n
    if Ea == 0 or Eb == 0:
        return IState(np.empty((0, n), dtype=object))
    perms = permutations(n)
    i, j, p = np.meshgrid(np.arange(Ea), np.arange(Eb), np.arange(len(perms)), indexing="ij")
    i, j, p = i.ravel(), j.ravel(), p.ravel()
    left = a.regions[i]
    right = np.take_along_axis(b.regions[j], perms[p], axis=1)
    inter = np.asarray(constrain(shapely.intersection(left, right), shape), dtype=object).reshape(left.shape)
    return clean_up(IState(inter), shape=shape)


def posteriors_bruteforce(node: np.ndarray, ch: Chains, bonus: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """(K2)-(K3) by enumeration of all ``K^n`` firer sequences (test oracle for short logs)."""
    K = len(ch.residents)
    bonus = np.zeros((len(node), K)) if bonus is None else bonus
    S = ch.log_t.shape[2]
    n = len(node)
    logs, seqs = [], []
    for z in product(range(K), repeat=n):
        last = [S] * K
        total = 0.0
        for i, r in enumerate(z):
            total += ch.log_t[r, last[r], node[i]] + bonus[i, r]
            last[r] = int(node[i])
        logs.append(total)
        seqs.append(z)
    logs = np.array(logs)
    log_z = float(logsumexp(logs))
    w = np.exp(logs - log_z)
    post = np.zeros((n, K))
    for wk, z in zip(w, seqs):
        post[np.arange(n), list(z)] += wk
    return post, log_z
