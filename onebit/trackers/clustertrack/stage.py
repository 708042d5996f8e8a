"""The ``clustertrack`` stage: proximity frames + site -> tracks, counts and consensus.

Inputs: ``proximity_frames`` (FRAMES: slot, t, sensor, on). The site's proximity sensors give
positions and radii; the problem is 1-D when every sensor has ``y == 0`` (a strip site),
2-D otherwise (``dim`` overrides).

Outputs (tables ``clustertrack_<key>``):

- ``tracks`` (TRACKS): the best particle of every final cluster (first run + Appendix B).
- ``track_info``: track, cost, origin (0 first run, k = k-th rerun).
- ``counts``: per instant t: size S_F, components, lower_bound (Theorem 4 / component count).
- ``minimal_targets`` (1-D): t, x of a minimal set of targets explaining each snapshot.
- ``feasible`` (1-D): t, component, lo, hi -- the intervals of F.
- ``steps``: per instant: candidates, scanned, kept, clusters, max_cluster (Algorithm 1).
- ``particles``: t, particle, cluster, x, y, cost -- the survivors of the first run.
- ``consensus``: run, track, cluster, cost, support (section 6, over ``consensus_runs`` seeds).
- ``params``: one row: dim, R, H, m_o, K, L, D0, Q_hat, A_hat, reruns, satisfied,
  count_lower_bound, count_consensus.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl

from onebit.core.parallel import available_cores, run_beside
from onebit.core.params import param, validate
from onebit.core.site import Site
from onebit.core.tables import FRAMES, TRACKS, check_schema, conform
from onebit.trackers.base import ARTIFACTS, TrackerSpec, instants_bound
from onebit.trackers.clustertrack.algorithm import Params, clustertrack, consensus, rules_of_thumb, seed_runs
from onebit.trackers.clustertrack.feasible import sensor_array
from onebit.trackers.clustertrack.space import FeasibleSpace

NAME = "clustertrack"


@dataclass(frozen=True, kw_only=True)
class ClusterTrackConfig:
    """Configuration of ``clustertrack`` (defaults: Singh et al., sections 5.1 and 5.3).

    Every length is relative to R (the sensors' mean radius, from the site's detection
    regions), so no field carries a unit and a ``run.toml`` means the same in any units.
    """

    h: int = param(25, "H, particles kept per cluster in 1-D (paper: 25)", lo=1, hi=100000)
    m_o_r: float = param(15.0, "sampling density m_o R in 1-D (paper: 15 samples per R)", lo=1e-6, hi=1e5)
    h_2d: int = param(50, "H in 2-D (paper: 50)", lo=1, hi=100000)
    m_o_r2: float = param(50.0, "m_o R^2 in 2-D (paper: 50)", lo=1e-6, hi=1e6)
    q_hat: int = param(
        0, "estimated number of targets; 0 = max over instants of the lower bound (paper)", lo=0, hi=10000
    )
    q_factor: float = param(1.0, "multiplies the rule-of-thumb Q_hat (the paper tried up to 2)", lo=1e-6, hi=100.0)
    k: int = param(0, "K; 0 = rule of thumb K = H Q_hat", lo=0, hi=10**7)
    l: int = param(0, "L; 0 = rule of thumb L = H m_o mean(S_F)", lo=0, hi=10**8)  # noqa: E741
    d0_r: float = param(0.0, "clustering threshold D_0 in units of R; 0 = rule of thumb A_hat^(1/n)", lo=0.0, hi=1e6)
    reruns: int = param(
        10,
        "Appendix B: reruns that must yield tracks not clustering with existing ones (paper: 10); 0 switches "
        'Appendix B off (the paper\'s "one-run version")',
        lo=0,
        hi=1000,
    )
    rerun_cost_ratio: float = param(
        10.0,
        "a rerun whose new tracks all cost more than this times the cheapest track (section 6's "
        '"significantly high cost") was monopolised by one cluster of its K = H q budget; it is repeated '
        "once with K = H Q_hat. 0 = the paper-literal rerun",
        lo=0.0,
        hi=1e9,
    )
    consensus_runs: int = param(
        4,
        "R runs (seeds seed .. seed+R-1) for the multi-run target count (the paper's suggestion in section 6, "
        "left open there; each run costs as much as the tracker itself, so 4 by default -- 2 minutes of a "
        "43-sensor array in ~8 s -- and 10 or more for a figure like the paper's 12b)",
        lo=0,
        hi=10000,
    )
    consensus_ratio: float = param(
        10.0, "drop consensus tracks costing more than this times the cheapest (10)", lo=1.0, hi=1e9
    )
    consensus_support: float = param(
        0.5, "a consensus cluster counts when at least this fraction of runs has a track in it", lo=0.0, hi=1.0
    )
    raster_per_r: int = param(10, "2-D raster cells per R", lo=1, hi=1000)
    dim: str = param("auto", "auto (1-D when every sensor has y == 0), 1d or 2d", choices=("auto", "1d", "2d"))
    targets: int = param(
        0,
        "most tracks returned (and so at once: a track spans the run); 0 = the site's targets. The result "
        "never exceeds min(targets, Q_hat)",
        lo=0,
        hi=10**4,
    )
    seed: int = param(0, "random seed", lo=0)
    max_instants: int = param(
        6000,
        "the most instants (frames) the pipeline runs it on; a longer log skips the stage, saying so: every "
        "instant is scanned once per run, and with the defaults there are about (1 + reruns) x "
        "(1 + consensus_runs) runs -- 7-11 ms per instant on the simulated 25-sensor line on 2 cores (each "
        "run's instant costs ~0.2 ms, in proportion to its m_t K candidates: the sensors on and the targets, "
        "not the site), so 6000 instants take 0.7-1.1 minutes. 0 = no bound",
        lo=0,
    )
    cores: int = param(
        0,
        "the most cores the independent runs use at once (the stage's own run and the consensus runs of the "
        "other seeds, each a whole CLUSTERTRACK with its reruns; onebit.core.parallel.run_beside). 0 = every "
        "core this process may use (1 inside a run-many pool), on a job of at least PARALLEL_MIN steps x "
        "candidates (below it, starting workers costs more than it saves); 1 = every run here. The output "
        "is the same for any value",
        lo=0,
        hi=4096,
    )

    def __post_init__(self) -> None:
        validate(self)


#: Schemas of the tables besides ``tracks`` (``feasible`` and ``minimal_targets`` in 1-D only,
#: ``consensus`` when ``consensus_runs > 0``).
OUTPUT_SCHEMAS: dict[str, pl.Schema] = {
    "track_info": pl.Schema({"track": pl.String, "cost": pl.Float64, "origin": pl.Int64}),
    "counts": pl.Schema({"t": pl.Float64, "size": pl.Float64, "components": pl.Int64, "lower_bound": pl.Int64}),
    "steps": pl.Schema(
        {
            "t": pl.Float64,
            "candidates": pl.Int64,
            "scanned": pl.Int64,
            "kept": pl.Int64,
            "clusters": pl.Int64,
            "max_cluster": pl.Int64,
        }
    ),
    "particles": pl.Schema(
        {
            "t": pl.Float64,
            "particle": pl.Int64,
            "cluster": pl.Int64,
            "x": pl.Float64,
            "y": pl.Float64,
            "cost": pl.Float64,
        }
    ),
    "feasible": pl.Schema({"t": pl.Float64, "component": pl.Int64, "lo": pl.Float64, "hi": pl.Float64}),
    "minimal_targets": pl.Schema({"t": pl.Float64, "x": pl.Float64}),
    "consensus": pl.Schema({"run": pl.Int64, "cluster": pl.Int64, "cost": pl.Float64, "support": pl.Float64}),
    "params": pl.Schema(
        {
            "dim": pl.Int64,
            "R": pl.Float64,
            "H": pl.Float64,
            "m_o": pl.Float64,
            "K": pl.Int64,
            "L": pl.Int64,
            "D0": pl.Float64,
            "Q_hat": pl.Int64,
            "A_hat": pl.Float64,
            "reruns": pl.Int64,
            "satisfied": pl.Boolean,
            "count_lower_bound": pl.Int64,
            "count_consensus": pl.Int64,
            "tracks": pl.Int64,
        }
    ),
}


def available(site: Site) -> str | None:
    return None if site.proximity_sensors else "site has no proximity sensors"


def fits(inputs: dict, site: Site, config: ClusterTrackConfig) -> str | None:
    """Reason to skip on these inputs, or ``None``: more instants than ``config.max_instants``."""
    return instants_bound(
        inputs.get("proximity_frames"), NAME, "max_instants", config.max_instants, "7-11 ms each with the defaults"
    )


def readings(frames: pl.DataFrame, ids: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
    """``(times (T,), on (T, n))`` from FRAMES, sensors in site order (absent = off)."""
    frames = frames.filter(pl.col("sensor").is_in(list(ids)))
    slots = frames.select("slot", "t").unique("slot").sort("slot")
    if slots.height == 0:
        return np.zeros(0), np.zeros((0, len(ids)), dtype=bool)
    si = frames["slot"].to_numpy()
    k = np.searchsorted(slots["slot"].to_numpy(), si)
    col = pl.Series(frames["sensor"]).replace_strict(list(ids), list(range(len(ids))), return_dtype=pl.Int64).to_numpy()
    on = np.zeros((slots.height, len(ids)), dtype=bool)
    on[k, col] = frames["on"].to_numpy()
    return slots["t"].to_numpy().astype(float), on


def build_space(
    frames: pl.DataFrame, site: Site, config: ClusterTrackConfig
) -> tuple[FeasibleSpace, float, np.ndarray]:
    """``(space, R, on (T, n))`` from the frames."""
    sa = sensor_array(site)
    times, on = readings(frames, sa.ids)
    dim = {"auto": 1 if sa.is_1d else 2, "1d": 1, "2d": 2}[config.dim]
    R = sa.radius
    return FeasibleSpace.build(on, times, sa, site.boundary, dim=dim, cell=R / config.raster_per_r), R, on


def params_for(space: FeasibleSpace, R: float, config: ClusterTrackConfig) -> Params:
    if space.dim == 1:
        H, m_o = config.h, config.m_o_r / R
    else:
        H, m_o = config.h_2d, config.m_o_r2 / R**2
    return rules_of_thumb(
        space, H=H, m_o=m_o, q_hat=config.q_hat, q_factor=config.q_factor, K=config.k, L=config.l, D0=config.d0_r * R
    )


def track_bound(p: Params, site: Site, config: ClusterTrackConfig) -> int:
    """Most tracks CLUSTERTRACK may return: its own count Q_hat (the counting bound of
    section 4.2.2, ``q_hat`` when given), and no more than ``targets`` (the config's, else
    the site's) when declared."""
    cap = config.targets or (site.targets or 0)
    return int(min(p.Q_hat, cap)) if cap else int(p.Q_hat)


def _xy(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x and y columns of ``(..., dim)`` positions (y = 0 in 1-D)."""
    return a[..., 0], (a[..., 1] if a.shape[-1] > 1 else np.zeros(a.shape[:-1]))


#: ``cores = 0`` runs the independent runs side by side from this many steps x candidates
#: (``T x L``): the 10^4-row simulated line has 4 749 x 2 779 = 13 M (its four runs ~45 s of
#: CPU), the real r1-easy ceiling array 230 x 21 857 = 5 M (~6 s); a worker costs about a
#: second to start (forked from a fresh interpreter, numba's kernels loaded from its cache).
PARALLEL_MIN = 2_000_000


def run_cores(config: ClusterTrackConfig, work: int, runs: int) -> int:
    """Lanes (this process and workers) for ``runs`` independent runs beside the stage's own:
    ``config.cores`` (0: :func:`available_cores` when ``work = T x L >= PARALLEL_MIN``, else
    1), at most ``1 + runs``."""
    if config.cores == 0:
        cores = available_cores() if work >= PARALLEL_MIN else 1
    else:
        cores = config.cores
    return max(1, min(cores, 1 + runs))


def run(inputs: dict, site: Site, config: ClusterTrackConfig) -> dict[str, pl.DataFrame]:
    """Feasible spaces, counts, CLUSTERTRACK with Appendix B, and the multi-run consensus."""
    frames = check_schema(inputs["proximity_frames"], FRAMES, name="proximity_frames")
    space, R, on = build_space(frames, site, config)
    T = space.T
    times = space.times
    if T == 0:  # no instant at all: every table empty, with its schema
        empty = {k: pl.DataFrame(schema=v) for k, v in OUTPUT_SCHEMAS.items()}
        if space.dim != 1:
            del empty["feasible"], empty["minimal_targets"]
        if config.consensus_runs == 0:
            del empty["consensus"]
        return {"tracks": pl.DataFrame(schema=TRACKS), **empty}
    p = params_for(space, R, config)
    bound = track_bound(p, site, config)
    seeds = list(range(config.seed, config.seed + config.consensus_runs))
    # the consensus's other runs (the stage's run is seed's when it is the same call: reruns on)
    others = [s for s in seeds if not (config.reruns > 0 and s == config.seed)]
    cores = run_cores(config, T * p.L, len(others))

    def here():
        return clustertrack(
            space,
            p,
            np.random.default_rng(config.seed),
            max_reruns=config.reruns,
            rerun=config.reruns > 0,
            record=True,
            high_cost=config.rerun_cost_ratio,
            max_tracks=bound,
        )

    # the other runs to cores - 1 workers, one seed a call; this process takes, once its own
    # run is done, every one no worker has started (run_beside)
    res, theirs = run_beside(
        here,
        seed_runs,
        [(space, p, [s], config.reruns, config.rerun_cost_ratio, bound) for s in others],
        workers=cores - 1,
    )
    made = {s: runs[0] for s, runs in zip(others, theirs)}
    names = [f"c{i + 1}" for i in range(res.tracks.shape[0])]
    out = {"tracks": _tracks(res, space, names)}
    out["track_info"] = pl.DataFrame(
        {"track": names, "cost": res.costs, "origin": res.origin},
        schema={"track": pl.String, "cost": pl.Float64, "origin": pl.Int64},
    )
    ncomp = np.array([cb.size for cb in space.comp_bounds_all], dtype=np.int64)
    out["counts"] = pl.DataFrame(
        {"t": times, "size": space.sizes_all, "components": ncomp, "lower_bound": space.bounds_all}
    )
    out["steps"], out["particles"] = _first_run(res.first, space)
    if space.dim == 1:
        out["feasible"], out["minimal_targets"] = _feasible_1d(space)
    count_consensus = -1
    if config.consensus_runs > 0:
        cons = consensus(
            space,
            p,
            seeds,
            ratio=config.consensus_ratio,
            min_support=config.consensus_support,
            max_reruns=config.reruns,
            high_cost=config.rerun_cost_ratio,
            known={**made, **({config.seed: res} if config.reruns > 0 else {})},
            max_tracks=bound,
        )  # every run is made above: the stage's (seed's) and the others, here or in workers
        count_consensus = cons.count
        out["consensus"] = pl.DataFrame(
            {
                "run": cons.run,
                "cluster": cons.cluster,
                "cost": cons.costs,
                "support": cons.support[cons.cluster] if cons.cluster.size else np.zeros(0),
            }
        )
    out["params"] = _params_row(space, R, p, res, count_consensus, len(names))
    out[ARTIFACTS] = _artifacts(space, R, on, config)
    return {k: (v.cast(dict(OUTPUT_SCHEMAS[k])) if k in OUTPUT_SCHEMAS else v) for k, v in out.items()}


def _tracks(res, space, names: list[str]) -> pl.DataFrame:
    """The tracks table of the stage's run: one row per track and instant, none at an instant
    whose F is empty."""
    T, times, N = space.T, space.times, len(names)
    x, y = _xy(res.tracks)
    tracks = conform(
        pl.DataFrame(
            {
                "tracker": NAME,
                "track": np.repeat(names, T) if N else np.array([], dtype=str),
                "t": np.tile(times, N),
                "x": x.ravel(),
                "y": y.ravel(),
            },
            schema_overrides={"track": pl.String},
        ),
        TRACKS,
    ).sort(["t", "track"], maintain_order=True)
    # an instant whose F is empty has no feasible position at all (every sensor off over a
    # fully covered site: nobody is there; or readings no target explains): no track rows there
    nowhere = np.array([cb.size == 0 for cb in space.comp_bounds_all], dtype=bool)
    if nowhere.any():
        tracks = tracks.filter(~pl.col("t").is_in(times[nowhere].tolist()))
    return tracks


def _first_run(fr, space) -> tuple[pl.DataFrame, pl.DataFrame]:
    """``(steps, particles)`` of the first run: the scan's counts per instant, and the
    survivors of every instant in one table (the per-instant arrays concatenated once)."""
    T, times = space.T, space.times
    steps = pl.DataFrame(
        {
            "t": times[space.order],
            "candidates": fr.candidates,
            "scanned": fr.scanned,
            "kept": fr.kept,
            "clusters": fr.clusters,
            "max_cluster": fr.max_cluster,
        }
    )
    n_t = np.array([fr.particles[t][1].size for t in range(T)], dtype=np.int64)
    pxy = np.concatenate([fr.particles[t][0] for t in range(T)]).reshape(-1, space.dim)
    px, py = _xy(pxy)
    particles = pl.DataFrame(
        {
            "t": np.repeat(times, n_t),
            "particle": np.arange(n_t.sum()) - np.repeat(np.cumsum(n_t) - n_t, n_t),
            "cluster": np.concatenate([fr.particles[t][1] for t in range(T)]).astype(np.int64),
            "x": px,
            "y": py,
            "cost": np.concatenate([fr.particles[t][2] for t in range(T)]).astype(np.float64),
        }
    )
    return steps, particles


def _feasible_1d(space) -> tuple[pl.DataFrame, pl.DataFrame]:
    """``(feasible, minimal_targets)`` of a 1-d site: F's components and the minimal target
    positions of every instant."""
    times = space.times
    n_c = np.array([len(f.components) for f in space.f1d], dtype=np.int64)
    comps = np.concatenate([f.components for f in space.f1d]).reshape(-1, 2)
    feasible = pl.DataFrame(
        {
            "t": np.repeat(times, n_c),
            "component": np.arange(n_c.sum()) - np.repeat(np.cumsum(n_c) - n_c, n_c),
            "lo": comps[:, 0],
            "hi": comps[:, 1],
        }
    )
    minimal = pl.DataFrame(
        {
            "t": np.repeat(times, [m.size for m in space.minimal_targets]),
            "x": np.concatenate(space.minimal_targets) if space.T else np.zeros(0),
        }
    )
    return feasible, minimal


def _params_row(space, R: float, p, res, count_consensus: int, n_tracks: int) -> pl.DataFrame:
    """The run's parameters and outcome, one row."""
    return pl.DataFrame(
        [
            {
                "dim": space.dim,
                "R": R,
                "H": p.H,
                "m_o": p.m_o,
                "K": p.K,
                "L": p.L,
                "D0": p.D0,
                "Q_hat": p.Q_hat,
                "A_hat": p.A_hat,
                "reruns": res.reruns,
                "satisfied": res.satisfied,
                "count_lower_bound": space.max_lower_bound,
                "count_consensus": count_consensus,
                "tracks": n_tracks,
            }
        ]
    )


def _artifacts(space, R: float, on, config: ClusterTrackConfig) -> dict:
    """What the viewer draws beside the tables: the instants, the frames on, the cells of F
    (2-d) and the cell size."""
    cells = None
    if space.dim == 2:
        ti, ci = np.nonzero(space.labels > 0)
        cxy = space.raster.centres[ci]
        cells = pl.DataFrame({"t": space.times[ti], "x": cxy[:, 0], "y": cxy[:, 1], "component": space.labels[ti, ci]})
    return {
        "times": space.times,
        "frames_on": on,
        "cells": cells,
        "cell": space.raster.cell if space.raster is not None else R / config.raster_per_r,
    }


SPEC = TrackerSpec(
    name=NAME,
    needs=("proximity_frames",),
    counts_people=True,
    config=ClusterTrackConfig,
    run=run,
    available=available,
    fits=fits,
    help="Singh et al.: target counting and CLUSTERTRACK from binary proximity sensors",
)
