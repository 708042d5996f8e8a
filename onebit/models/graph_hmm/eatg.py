"""Extended Activity Transition Graph (EATG), paper section III-B1.

``G = (M, E', E'', A', A'')``: nodes are the motion sensors, ``E'`` joins nodes that are
physically 1 hop apart (the site's sensor graph), ``E''`` joins nodes 2 hops apart. The
weights are activity-transition probabilities:

* ``a'(j2, j1)`` (eq. 1) -- the node active in the next slot::

      a'(j2, j1) = #{t : b_j2(t) = 1 and b_j1(t + T) = 1} / #{t : b_j2(t) = 1},

  counted over the closed 1-hop neighbourhood of ``j2`` (``j1 = j2`` is a user staying).
* ``a''(j3, j1)`` (eq. 2) -- the node activity reaches *two hops on*. Counted literally with a
  fixed lag of 2T the statistic is dominated by users dwelling at a node (a node stays on for
  several 1-s slots), so a user passing ``95 -> 99 -> 111`` would count for ``a''(95, 95)`` and
  not for ``a''(95, 111)``, which contradicts the paper's worked example (section III-C, where
  ``a''(111, 95) > a''(111, 111)``). We therefore count *triggers* (onsets, ``b_j(t) = 1`` and
  ``b_j(t - T) = 0``)::

      a''(j3, j1) = #{onset of j3 at t, onset of j1 in (t, t + L T]} / #{onset of j3}

  over ``j1`` at hop distance 2 from ``j3``, with horizon ``L`` (the HMM window ``d_max``).
  Turning back (``j1 = j3``) is not counted from data -- a re-trigger of one node is mostly a
  PIR burst of a user who never left -- and keeps its layout-prior weight. Each row is
  smoothed with the layout prior below (pseudo-count ``prior_strength``) and normalised.

Layout prior (used alone when no training data exists): ``a'`` stays with probability
``stay`` and moves to each 1-hop neighbour with ``(1 - stay) / deg``; ``a''`` is the 2-step
non-backtracking walk: from ``j3`` to a neighbour ``m`` (``1/deg(j3)``), then back to ``j3``
with probability ``turn_back`` (1 at a dead end) or on to each other neighbour of ``m``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.errors import InputError
from onebit.core.lazy import lazy_module

nx = lazy_module("networkx")
_csgraph = lazy_module("scipy.sparse.csgraph")
_sparse = lazy_module("scipy.sparse")


@dataclass(frozen=True)
class Eatg:
    """Node ids, hop distances and the activity-transition matrices ``a1 = A'``, ``a2 = A''``."""

    nodes: tuple[str, ...]
    hops: np.ndarray  # (N, N) int, shortest hop count in the 1-hop graph (large when unreachable)
    a1: np.ndarray  # (N, N) rows sum to 1, nonzero only for hops <= 1
    a2: np.ndarray  # (N, N) rows sum to 1, nonzero only for hops in {0, 2}

    @property
    def index(self) -> dict[str, int]:
        return {n: i for i, n in enumerate(self.nodes)}

    def table(self) -> pl.DataFrame:
        """Long table: kind (``a1`` 1-hop / ``a2`` 2-hop), src, dst, weight, hops."""
        rows = []
        for kind, mat in (("a1", self.a1), ("a2", self.a2)):
            i, j = np.nonzero(mat)
            rows.append(
                pl.DataFrame(
                    {
                        "kind": [kind] * len(i),
                        "src": np.asarray(self.nodes, dtype=object)[i].tolist(),
                        "dst": np.asarray(self.nodes, dtype=object)[j].tolist(),
                        "weight": mat[i, j],
                        "hops": self.hops[i, j].astype(np.int64),
                    },
                    schema={
                        "kind": pl.String,
                        "src": pl.String,
                        "dst": pl.String,
                        "weight": pl.Float64,
                        "hops": pl.Int64,
                    },
                )
            )
        return pl.concat(rows)

    def to_networkx(self) -> nx.DiGraph:
        """Directed graph with edge attributes ``a1`` (E') and ``a2`` (E'')."""
        g = nx.DiGraph()
        g.add_nodes_from(self.nodes)
        for kind, mat in (("a1", self.a1), ("a2", self.a2)):
            i, j = np.nonzero(mat)
            for a, b, w in zip(i.tolist(), j.tolist(), mat[i, j].tolist()):
                g.add_edge(self.nodes[a], self.nodes[b], **{kind: w})
        return g


def eatg_from_table(table: pl.DataFrame, nodes: tuple[str, ...], hops: np.ndarray, *, source: str = "eatg") -> Eatg:
    """The EATG of an ``eatg`` table (:meth:`Eatg.table`: kind, src, dst, weight) -- one learned
    from a training log by an earlier run (``tables/findinghumo_eatg.parquet``) -- on the
    site's ``nodes`` and ``hops``. Rows of a node the table does not name stay (weight 1 on
    the diagonal); each row is renormalised. A node the site does not have is an error naming
    ``source``: the graph belongs to another site."""
    need = {"kind", "src", "dst", "weight"}
    if not need <= set(table.columns):
        raise InputError(f"an EATG table needs the columns {sorted(need)}; it has {table.columns}", file=source)
    idx = {n: i for i, n in enumerate(nodes)}
    unknown = sorted((set(table["src"].to_list()) | set(table["dst"].to_list())) - set(idx))
    if unknown:
        raise InputError(f"nodes {unknown[:5]} are not sensor-graph nodes of this site", file=source)
    mats = {}
    for kind, allowed in (("a1", hops <= 1), ("a2", (hops == 2) | np.eye(len(nodes), dtype=bool))):
        part = table.filter(pl.col("kind") == kind)
        m = np.zeros((len(nodes), len(nodes)))
        i = np.array([idx[x] for x in part["src"].to_list()], dtype=np.int64)
        j = np.array([idx[x] for x in part["dst"].to_list()], dtype=np.int64)
        w = part["weight"].cast(pl.Float64).to_numpy()
        if (w < 0).any() or not np.isfinite(w).all():
            raise InputError(f"'{kind}' weights must be finite and >= 0", file=source)
        if i.size and not allowed[i, j].all():
            raise InputError(f"'{kind}' has an edge the site's hop distances do not allow", file=source)
        m[i, j] = w
        mats[kind] = _normalise(m, fallback_diag=True)
    return Eatg(tuple(nodes), hops, mats["a1"], mats["a2"])


def read_eatg(path: str, nodes: tuple[str, ...], hops: np.ndarray) -> Eatg:
    """:func:`eatg_from_table` of a ``.parquet`` or ``.csv`` file."""
    p = Path(path)
    if not p.is_file():
        raise InputError("EATG file not found", file=p)
    table = pl.read_parquet(p) if p.suffix == ".parquet" else pl.read_csv(p)
    return eatg_from_table(table, nodes, hops, source=str(p))


def hop_matrix(nodes: tuple[str, ...], edges) -> np.ndarray:
    """(N, N) shortest hop counts of the undirected 1-hop graph (N + 1 where unreachable)."""
    idx = {n: i for i, n in enumerate(nodes)}
    n = len(nodes)
    e = np.array([(idx[a], idx[b]) for a, b in edges], dtype=np.int64).reshape(-1, 2)
    adj = _sparse.csr_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
    d = _csgraph.shortest_path(adj, directed=False, unweighted=True)
    d[~np.isfinite(d)] = n + 1
    return d.astype(np.int64)


def layout_eatg(nodes: tuple[str, ...], hops: np.ndarray, *, stay: float = 0.6, turn_back: float = 0.05) -> Eatg:
    """EATG from the physical layout alone (see module docstring)."""
    adj = (hops == 1).astype(float)
    deg = adj.sum(axis=1)
    safe = np.maximum(deg, 1.0)
    a1 = adj * ((1.0 - stay) / safe)[:, None]
    a1[np.diag_indices_from(a1)] = np.where(deg > 0, stay, 1.0)
    # step 1: j3 -> m uniformly; step 2: m -> j3 with turn_back (1 at a dead end), else on
    step1 = adj / safe[:, None]  # (j3, m)
    back = np.where(deg <= 1, 1.0, turn_back)  # per m
    onward = adj / np.maximum(deg - 1, 1.0)[:, None] * (1.0 - back)[:, None]  # (m, j1), j1 != prev
    a2 = step1 @ onward  # includes paths m -> j3 itself; remove and re-add as turn-back
    a2[np.diag_indices_from(a2)] = 0.0
    a2 = np.where(hops == 2, a2, 0.0)
    a2[np.diag_indices_from(a2)] = step1 @ back
    a2 = _normalise(a2, fallback_diag=True)
    return Eatg(tuple(nodes), hops, _normalise(a1, fallback_diag=True), a2)


def onsets(active: np.ndarray) -> np.ndarray:
    """(D, N) bool: node turned on in this slot (was off in the previous one)."""
    prev = np.vstack([np.zeros((1, active.shape[1]), bool), active[:-1]])
    return active & ~prev


def trained_eatg(
    active: np.ndarray,
    nodes: tuple[str, ...],
    hops: np.ndarray,
    *,
    horizon: int = 5,
    prior_strength: float = 2.0,
    stay: float = 0.6,
    turn_back: float = 0.05,
) -> Eatg:
    """EATG learned from slot activity ``active`` (D, N) bool (eqs. 1 and 2, module docstring).

    Vectorised: eq. (1) is one matrix product of consecutive slots; eq. (2) counts onset pairs
    with a lag of 1..``horizon`` slots as a sum of ``horizon`` matrix products.
    """
    prior = layout_eatg(nodes, hops, stay=stay, turn_back=turn_back)
    active = np.asarray(active, bool)
    if active.shape[0] < 2:
        return prior
    c1 = lag_counts(active, 1)  # (j2, j1) counts of j2 at t and j1 at t+1
    c1 = np.where(hops <= 1, c1, 0.0)
    a1 = _normalise(c1 + prior_strength * prior.a1, fallback_diag=True)
    on = onsets(active)
    c2 = np.zeros_like(c1)
    for lag in range(1, horizon + 1):  # loop over lags, each a sparse (N, N) product
        if lag < on.shape[0]:
            c2 += lag_counts(on, lag)
    c2 = np.where(hops == 2, c2, 0.0)  # re-triggers of one node are mostly PIR bursts: prior only
    a2 = _normalise(c2 + prior_strength * prior.a2, fallback_diag=True)
    return Eatg(tuple(nodes), hops, a1, a2)


def lag_counts(x: np.ndarray, lag: int) -> np.ndarray:
    """``(N, N)`` float counts ``x[:-lag].T @ x[lag:]`` of a ``(D, N)`` bool activity: how often
    node ``i`` is on at ``t`` and node ``j`` at ``t + lag``. A sparse integer product (the
    activity of a day is a few percent of its slots x nodes): exact counts, the dense float
    product's values, without a ``D x N`` float copy per lag."""
    from scipy import sparse  # deferred: scipy's import is not free

    a = sparse.csc_matrix(x[:-lag].astype(np.int32))
    b = sparse.csc_matrix(x[lag:].astype(np.int32))
    return np.asarray((a.T @ b).toarray(), dtype=float)


def _normalise(m: np.ndarray, *, fallback_diag: bool) -> np.ndarray:
    m = np.asarray(m, float).copy()
    s = m.sum(axis=1)
    zero = s <= 0
    if fallback_diag and zero.any():
        m[zero, np.flatnonzero(zero)] = 1.0
        s = m.sum(axis=1)
    return m / s[:, None]
