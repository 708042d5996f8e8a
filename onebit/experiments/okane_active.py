"""Active tracking with I-states, simulated (O'Kane, section VIII).

:func:`simulate_active`: ``m`` mobile trackers, each with 9 square sensing regions in a 3 x 3
grid around it, its own I-state, what it knows of the other trackers' positions (the last
position heard, grown by ``s_trk`` per stage since), communication within ``r_c`` (I-states
intersected, knowledge shared), destination selection and matching of section VII; ``n``
targets moving along shortest paths to random destinations, the first ``m`` starting near a
tracker. The environment is :func:`~onebit.datasets.okane_sim.fig9_environment`. Inherently
sequential over stages (each depends on the last); vectorised within a stage. It runs the
I-state tracker, so it is an experiment, not a simulator (datasets import only the base and
the models).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely

from onebit.core.config import check_choice, check_range
from onebit.core.lazy import lazy_module
from onebit.datasets.okane_sim import TargetMotion, _free, fig9_environment, random_free_points
from onebit.models.walking import ShortestPaths, advance
from onebit.trackers.istate.active import match_destinations, performance, select_destinations, worst_distances
from onebit.trackers.istate.core import IState, cap_elements, communicate, contains, info_state_update

nx = lazy_module("networkx")


@dataclass(frozen=True, kw_only=True)
class ActiveConfig:
    """Active tracking simulation (section VIII); lengths in units of the 100 x 100 environment.

    trackers m, targets n, stages, max_elements M (paper: 10), shape of regions (paper:
    rectangles), s_tgt / s_trk largest moves per stage, r_c communication range, cell the
    side of each of the 9 sensing squares, start_radius how near a tracker the first m
    targets start, p_miss the false-negative probability of a sensing square.
    """

    trackers: int = 2
    targets: int = 3
    stages: int = 1000
    max_elements: int = 10
    shape: str = "rect"
    s_tgt: float = 1.0
    s_trk: float = 1.5
    r_c: float = 25.0
    cell: float = 5.0
    start_radius: float = 3.0
    p_miss: float = 0.0

    def __post_init__(self) -> None:

        check_range(self, "trackers", 1, 16, types=(int,))
        check_range(self, "targets", 1, 8, types=(int,))
        check_range(self, "stages", 1, None, types=(int,))
        check_range(self, "max_elements", 1, 1000, types=(int,))
        check_choice(self, "shape", ("exact", "rect", "disk"))
        for f in ("s_tgt", "s_trk", "r_c", "cell", "start_radius"):
            check_range(self, f, 0.0, None)
        check_range(self, "p_miss", 0.0, 1.0)


@dataclass(frozen=True)
class ActiveResult:
    targets: np.ndarray  # (K, n, 2)
    trackers: np.ndarray  # (K, m, 2)
    destinations: np.ndarray  # (K, m, 2)
    elements: np.ndarray  # (K, m)
    contained: np.ndarray  # (K, m) the tracker's I-state holds the true state
    links: list  # per stage (L, 2, 2)
    sensing: np.ndarray  # (K, m) object: the 9 squares of each tracker
    performance: np.ndarray  # (K,) P_k of Eq. (1)
    regions0: list  # per stage, tracker 0's I-state regions (E, n)


def sensing_squares(p: np.ndarray, cell: float) -> np.ndarray:
    """The 9 square sensing regions of a tracker at ``p``: a 3 x 3 grid of side ``cell``."""
    off = (np.arange(3) - 1) * cell
    cx, cy = np.meshgrid(p[0] + off, p[1] + off, indexing="ij")
    h = cell / 2
    return shapely.box(cx.ravel() - h, cy.ravel() - h, cx.ravel() + h, cy.ravel() + h)


def _communicate(trk: np.ndarray, eta: list, last_pos: np.ndarray, last_seen: np.ndarray, k: int, cfg: ActiveConfig):
    """Communication at stage ``k`` within ``r_c`` (section VI-B): each connected group of
    trackers shares one intersected I-state and its freshest knowledge of every tracker
    (``eta``, ``last_pos``, ``last_seen`` updated in place). Returns the links ``(L, 2, 2)``."""
    m = len(trk)
    d = np.hypot(*(trk[:, None, :] - trk[None, :, :]).transpose(2, 0, 1))
    g = nx.Graph()
    g.add_nodes_from(range(m))
    ii, jj = np.nonzero(np.triu(d <= cfg.r_c, 1))
    g.add_edges_from(zip(ii.tolist(), jj.tolist()))
    for comp in nx.connected_components(g):
        comp = sorted(comp)
        if len(comp) < 2:
            continue
        merged = eta[comp[0]]
        for o in comp[1:]:
            merged = cap_elements(communicate(merged, eta[o], shape=cfg.shape), cfg.max_elements, shape=cfg.shape)
        best = np.argmax(last_seen[comp], axis=0)  # freshest knowledge of each tracker
        fresh_pos = last_pos[np.asarray(comp)[best], np.arange(m)]
        fresh_seen = last_seen[np.asarray(comp)[best], np.arange(m)]
        for j in comp:
            eta[j] = merged
            last_pos[j], last_seen[j] = fresh_pos, fresh_seen
            last_pos[j, comp], last_seen[j, comp] = trk[comp], k
    return np.stack([trk[ii], trk[jj]], axis=1) if len(ii) else np.zeros((0, 2, 2))


def simulate_active(cfg: ActiveConfig, *, seed: int, environment=None, record_regions: bool = False) -> ActiveResult:
    """Run one active-tracking trial (see the module docstring)."""
    rng = np.random.default_rng(seed)
    boundary, obstacles = environment or fig9_environment()
    free = _free(boundary, obstacles)
    planner = ShortestPaths(free, margin=0.05)
    m, n, K = cfg.trackers, cfg.targets, cfg.stages
    trk = random_free_points(rng, free, m)
    start = random_free_points(rng, free, n)
    for i in range(min(m, n)):  # the first m targets start near a tracker
        near = random_free_points(rng, free.intersection(shapely.Point(trk[i]).buffer(cfg.start_radius)), 1)
        start[i] = near[0]
    targets = TargetMotion(rng, planner, start, np.full(n, cfg.s_tgt))
    eta = [IState.initial(free, n) for _ in range(m)]
    last_pos = np.broadcast_to(trk, (m, m, 2)).copy()  # last_pos[j, o]: where j last knew o
    last_seen = np.zeros((m, m), dtype=np.int64)
    out_t = np.zeros((K, n, 2))
    out_p = np.zeros((K, m, 2))
    out_d = np.zeros((K, m, 2))
    out_e = np.zeros((K, m), dtype=np.int64)
    out_c = np.zeros((K, m), dtype=bool)
    out_s = np.empty((K, m), dtype=object)
    links, regs0 = [], []

    for k in range(K):  # inherently sequential
        q = targets.move() if k else targets.pos.copy()
        out_t[k] = q
        # sensing and the filter of every tracker
        for j in range(m):
            sq = sensing_squares(trk[j], cfg.cell)
            out_s[k, j] = shapely.union_all(sq)
            hit = shapely.contains_xy(sq[:, None], q[None, :, 0], q[None, :, 1]).any(axis=1)
            hit &= rng.random(9) >= cfg.p_miss
            eta[j] = info_state_update(
                eta[j],
                sq[hit],
                step=cfg.s_tgt if k else 0.0,
                free_space=free,
                shape=cfg.shape,
                max_elements=cfg.max_elements,
            )
        links.append(_communicate(trk, eta, last_pos, last_seen, k, cfg))
        for j in range(m):
            last_pos[j, j], last_seen[j, j] = trk[j], k
            out_e[k, j] = eta[j].size
            out_c[k, j] = contains(eta[j], q)
        if record_regions:
            regs0.append(eta[0].regions.copy())
        out_p[k] = trk
        # destinations, matching, movement
        new = trk.copy()
        for j in range(m):
            dest = select_destinations(eta[j], free, m)
            possible = [
                shapely.Point(trk[o]).buffer(1e-9)
                if o == j
                else shapely.Point(last_pos[j, o]).buffer(max(cfg.s_trk * (k - last_seen[j, o]), 1e-9), quad_segs=4)
                for o in range(m)
            ]
            mine = dest[match_destinations(worst_distances(possible, dest))[j]]
            out_d[k, j] = mine
            new[j] = advance(planner.path(trk[j], mine), cfg.s_trk)
        trk = new
    return ActiveResult(out_t, out_p, out_d, out_e, out_c, links, out_s, performance(out_t, out_p), regs0)
