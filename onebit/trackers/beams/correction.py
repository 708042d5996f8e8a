"""False-negative correction of the crossing string (Bobadilla et al. V).

Runs after the reader stages and before the trackers, when the number of agents ``n`` is
known (``site.toml`` ``targets`` or ``run.toml`` ``[correct] n``). The ``[correct]`` section
comes from ``--config``; when that has none, from the dataset's own ``run.toml`` (the beams
simulator writes ``n`` and the known initial counts there -- the paper's known ``eta_0``).
It checks the observed string against the counting automaton M_C and inserts the fewest
crossings that make it a string of ``L(M_C)`` (:mod:`onebit.trackers.beams.counting`), each
at the middle in time of its feasible window (``placement``). The pipeline's stage list feeds
``corrected_crossings`` to the ``beams`` tracker when this stage ran.

Initial count vector ``eta_0``, in order of precedence:

1. ``[correct] initial = {r1 = 2, r4 = 1}`` -- counts per region (sum = n);
2. ``[correct] start_region = "r2"`` -- all n agents start there (the lab experiment, Fig. 9a);
3. otherwise unknown: every ``eta_0`` with ``sum = n`` is a free start state and the DP
   picks the one that needs the fewest insertions (reported as table ``correct_initial``).

Tables: ``corrected_crossings`` (CROSSINGS + ``inserted: Boolean``), ``correct_insertions``
(every inserted crossing: t, beam, direction, index in the corrected string, the observed
crossing it precedes, source and target region), ``correct_initial`` (region, count).
Report: ``correct/accepted`` (1 if the observed string is already in ``L(M_C)``),
``correct/first_violation`` (index of the first unexplainable crossing, -1 if none),
``correct/inserted``, ``correct/n``, ``correct/peak_states``; the ``scores`` stage adds
``correct/recovered`` in simulation (:func:`onebit.scoring.correction.recovered_matches`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl

from onebit.core.config import MAX_TARGETS
from onebit.core.errors import ConfigError
from onebit.core.params import param, validate
from onebit.core.region_graph import RegionGraph
from onebit.core.tables import CROSSINGS, check_schema
from onebit.trackers.beams.counting import (
    PLACEMENTS,
    RegionEdges,
    correct,
    first_count_violation,
    minimal_initial_counts,
    verify,
)

#: The corrected crossing string: CROSSINGS plus whether each crossing was inserted.
CORRECTED_CROSSINGS = pl.Schema({**dict(CROSSINGS), "inserted": pl.Boolean})


@dataclass(frozen=True)
class CorrectionResult:
    """The correction's tables and its report rows ``(stage, metric, value, unit)``."""

    tables: dict[str, pl.DataFrame]
    report: list[tuple[str, str, float, str]]


@dataclass(frozen=True, kw_only=True)
class CorrectConfig:
    """``run.toml`` ``[correct]``: the counting correction of section V."""

    n: int | None = param(
        None, "number of agents (section V assumes it known); unset = site.toml targets", lo=1, hi=MAX_TARGETS
    )
    initial: dict | None = param(None, "known initial counts per region name (sum = n); unset = not known")
    start_region: str | None = param(None, "all n agents start in this region; used when initial is not given")
    placement: str = param(
        "midpoint",
        "where an inserted crossing goes in its feasible window: earliest (as early as the counts allow), "
        "latest (right before the crossing that needs it) or midpoint (the middle in time of that window, "
        "onebit.trackers.beams.counting.place_insertions)",
        choices=PLACEMENTS,
    )
    window: int = param(4096, "how many crossings back an insertion may be moved", lo=1)
    enabled: bool = param(
        True,
        "false skips the stage (e.g. to compare with the uncorrected string when the dataset's run.toml "
        "would turn it on)",
    )

    def __post_init__(self) -> None:
        validate(self)
        if self.initial is not None:
            if not isinstance(self.initial, dict) or not self.initial:
                raise ConfigError(f"CorrectConfig.initial = {self.initial!r}; expected a table region -> count")
            for k, v in self.initial.items():
                if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                    raise ConfigError(f"CorrectConfig.initial.{k} = {v!r}; expected a count >= 0")


def initial_counts(cfg: CorrectConfig, names: tuple[str, ...], n: int) -> np.ndarray | None:
    """``eta_0`` from the config (region names checked against the region graph), or None."""
    idx = {r: i for i, r in enumerate(names)}
    if cfg.initial is not None:
        unknown = sorted(set(cfg.initial) - set(idx))
        if unknown:
            raise ConfigError(f"[correct] initial: unknown region(s) {unknown}; regions are {list(names)}")
        eta = np.zeros(len(names), dtype=np.int64)
        for r, c in cfg.initial.items():
            eta[idx[r]] = c
        if int(eta.sum()) != n:
            raise ConfigError(f"[correct] initial: counts sum to {int(eta.sum())}, but n = {n}")
        return eta
    if cfg.start_region is not None:
        if cfg.start_region not in idx:
            raise ConfigError(
                f"[correct] start_region = {cfg.start_region!r}: unknown region; regions are {list(names)}"
            )
        eta = np.zeros(len(names), dtype=np.int64)
        eta[idx[cfg.start_region]] = n
        return eta
    return None


def corrected_frame(crossings: pl.DataFrame, res, edges: RegionEdges) -> pl.DataFrame:
    """The corrected string as a CORRECTED_CROSSINGS frame.

    Observed rows keep their time; inserted rows get the time their placement chose
    (``res.time``, the timed placements); otherwise a run of ``K`` inserted crossings between
    observed times ``t_a`` and ``t_b`` gets ``t_a + (t_b - t_a) k / (K + 1)``, k = 1..K
    (``t_b`` alone before the first observed crossing, ``t_a`` alone after the last).
    """
    ob = crossings.select("t", "beam", "direction")
    if ob.height == 0:  # nothing observed, nothing inserted
        return pl.DataFrame(schema=CORRECTED_CROSSINGS)
    ins = res.inserted
    placed = np.where(ins, res.time, np.nan) if res.time is not None else np.full(len(ins), np.nan)
    obs_row = np.where(ins, 0, res.observed_index)
    edge = np.where(ins, res.edge, 0)
    beams = pl.Series(list(edges.edge_beam), dtype=pl.String).gather(edge)
    dirs = np.asarray(edges.edge_direction, dtype=np.int8)[edge]
    df = pl.DataFrame(
        {
            "t_obs": pl.Series(ob["t"].to_numpy()[obs_row]).scatter(np.flatnonzero(ins), None),
            "beam": pl.select(pl.when(pl.Series(ins)).then(beams).otherwise(ob["beam"].gather(obs_row))).to_series(),
            "direction": pl.Series(np.where(ins, dirs, ob["direction"].to_numpy()[obs_row]), dtype=pl.Int8),
            "inserted": pl.Series(ins, dtype=pl.Boolean),
            "t_placed": pl.Series(placed, dtype=pl.Float64).fill_nan(None),
        }
    )
    run = (~pl.col("inserted")).cum_sum()
    df = df.with_columns(
        prev=pl.col("t_obs").forward_fill(),
        next=pl.col("t_obs").backward_fill(),
        k=pl.int_range(pl.len()).over(run),
        big_k=pl.len().over(run),
    )
    # in a run led by an observed row, inserted rows are k = 1..K with K = len - 1; a run at the
    # very start has no observed row and k = 0..K-1
    lead_obs = pl.col("prev").is_not_null()
    k = pl.when(lead_obs).then(pl.col("k")).otherwise(pl.col("k") + 1)
    kk = pl.when(lead_obs).then(pl.col("big_k") - 1).otherwise(pl.col("big_k"))
    interp = pl.col("prev") + (pl.col("next") - pl.col("prev")) * k / (kk + 1)
    t = pl.coalesce(pl.col("t_obs"), pl.col("t_placed"), interp, pl.col("next"), pl.col("prev"))
    return df.select(t.cast(pl.Float64).alias("t"), "beam", "direction", "inserted")


def run_correction(crossings: pl.DataFrame, rg: RegionGraph, cfg: CorrectConfig, n: int) -> CorrectionResult:
    """Check the observed string against M_C and insert the fewest crossings (section V).

    ``crossings`` (CROSSINGS), the region graph, the config and the number of agents ``n``.
    Returns the tables ``corrected_crossings``, ``correct_insertions``, ``correct_initial``
    and the report rows (module docstring).
    """
    edges = RegionEdges.from_region_graph(rg)
    crossings = check_schema(crossings, CROSSINGS, name="crossings").sort("t", maintain_order=True)
    src, tgt = rg.endpoint_arrays(crossings["beam"], crossings["direction"].to_numpy())
    eta0 = initial_counts(cfg, rg.names, n)
    if eta0 is not None:
        ver = verify(src, tgt, eta0)
        accepted, first = ver.accepted, ver.first_violation
    else:
        need = minimal_initial_counts(src, tgt, len(rg.names))
        accepted = int(need.sum()) <= n
        first = -1 if accepted else first_count_violation(src, tgt, len(rg.names), n)
    res = correct(
        src,
        tgt,
        edges,
        n_agents=n,
        initial=eta0,
        placement=cfg.placement,
        window=cfg.window,
        times=crossings["t"].to_numpy(),
    )
    names = pl.Series("region", list(rg.names), dtype=pl.String)  # gathered by index below
    corrected = corrected_frame(crossings, res, edges)
    pos = res.insertion_positions
    # the observed crossing each insertion precedes: next non-negative observed_index
    nxt = np.minimum.accumulate(
        np.where(res.observed_index >= 0, np.arange(len(res.inserted)), len(res.inserted))[::-1]
    )[::-1]
    before = np.r_[res.observed_index, -1][nxt[pos]].astype(np.int64)
    insertions = (
        corrected.with_row_index("index")
        .filter(pl.col("inserted"))
        .select(
            "t",
            "beam",
            "direction",
            pl.col("index").cast(pl.Int64),
            pl.Series("before", before, dtype=pl.Int64).replace(-1, None),
            names.gather(res.source[pos]).alias("source"),
            names.gather(res.target[pos]).alias("target"),
        )
    )
    initial = pl.DataFrame({"region": list(rg.names), "count": res.initial.astype(np.int64)})
    rows = [
        ("correct", "n", float(n), "agents"),
        ("correct", "accepted", 1.0 if accepted else 0.0, "flag"),
        ("correct", "first_violation", float(first), "index"),
        ("correct", "inserted", float(res.cost), "crossings"),
        ("correct", "peak_states", float(res.peak_states), "count states"),
    ]
    tables = {"corrected_crossings": corrected, "correct_insertions": insertions, "correct_initial": initial}
    return CorrectionResult(tables, rows)
