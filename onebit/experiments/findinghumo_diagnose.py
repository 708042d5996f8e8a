"""``onebit experiment findinghumo-diagnose OUT``: every identity swap of the HMM trackers.

The diagnosis behind ``docs/findinghumo.md`` (issue #15). For each seed of the issue's setting
(the hallway, 3 users, 150 s, drop 0.02; seeds ``seed .. seed + trials - 1``, default 0-19),
the dataset is simulated into a temporary folder and read back as the pipeline reads it, the
trackers (:data:`TRACKERS`) are run as stage functions on it, and their tracks are scored
with the pipeline's own scorer
(:func:`onebit.scoring.findinghumo.score`, the ``hop_error`` of ``onebit report``).

Identity swaps. Let ``n_v(s)`` be the true node of user ``v`` at slot ``s`` (the truth sample
nearest the slot's mid time, node as the scorer computes it) and ``p_u(s)`` the node of
decoded track ``u``. The per-slot assignment ``pi_s`` (decoded track of each true user) is the
one-to-one matching minimising ``sum_v hops(n_v(s), p_pi_s(v)(s))``; among equally good
matchings the one of the previous slot is kept, and an assignment held for fewer than
``MIN_RUN`` slots is a lag (a track a slot behind its user as two users pass), not a swap.
A *swap* is a slot where ``pi_s`` differs from ``pi_{s-1}``: from there on the tracks
follow other users. For each swap the table gives:

* ``slot``, the true ``users`` whose track changed, their true nodes (``true_nodes``) and the
  nodes of the tracks that followed them before (``track_nodes``);
* ``meet``: the users were within 1 hop of each other (truth) within ``+-MEET_SLOTS`` slots --
  a co-location, where binary sensors cannot tell who is who -- and ``kind``, from the true
  moves within ``KIND_SLOTS`` slots of the swap: ``co-walk`` (they walked an edge the same way:
  together, or one following or overtaking the other; the activations are those of one
  group, and who is who only shows in timing), ``crossing`` (they walked an edge against each
  other, or came from different nodes and left to different nodes: resolvable in principle
  by the direction prior a''), ``same-in`` (arrived from the same node, left apart: a'' is
  symmetric in the users), ``same-out`` (arrived apart, left together), ``none`` (no
  meeting: a decoding error away from other users);
* ``event``: the interaction graph of the paths CPDA (``findinghumo``) or the flow started from holds a
  co-location event of these tracks within ``+-MEET_SLOTS`` slots, and for ``findinghumo``
  ``cpda``: what CPDA decided there (``switch`` / ``keep``, with the posterior of the pairing
  chosen and of keeping the HMM's pairing); ``cpda_tie``: one of those decisions had another
  pairing as probable as the HMM's -- the paper's CPT a'' cannot choose there.

A bound per seed and tracker: ``slot_error``, the identity-free error of its positions (the
best matching of every slot on its own): no relabelling of its tracks -- CPDA, the flow, any
association -- can score lower.

Writes ``swaps.csv`` (one row per swap), ``results.csv`` (per seed and tracker: hop error,
swaps) and ``summary.csv`` (per tracker: mean hop error, swaps by kind) and prints the summary.
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core import writers
from onebit.core.lazy import lazy_module
from onebit.core.site import Site, load_site
from onebit.datasets.hallway_sim import write_hallway_dataset
from onebit.experiments.trials import format_table, run_trials, write_timings
from onebit.models.graph_hmm.decoding import tracks_table
from onebit.models.graph_hmm.eatg import hop_matrix
from onebit.models.graph_hmm.likelihood import exchange_margin, tie_relabelling
from onebit.pipeline.executors import Executor
from onebit.pipeline.stages import TRACKERS as ENTRIES
from onebit.readers.motion import read_motion_csv
from onebit.scoring.findinghumo import score, truth_nodes
from onebit.trackers.findinghumo.cpda import colocation_events

_optimize = lazy_module("scipy.optimize")

TRACKERS = ("hmm1", "hmm2", "findinghumo", "findinghumo-flow")
#: the order the trackers are run in: findinghumo-flow right after hmm2, whose decode it shares
_SHARING_ORDER = ("hmm1", "hmm2", "findinghumo-flow", "findinghumo")
SEEDS = 20
DURATION = 150.0
USERS = 3
DROP = 0.02
#: a swap is "at" a meeting / interaction-graph event when one lies within this many slots
MEET_SLOTS = 3
#: a swap's kind is read from the true moves this many slots either side of it
KIND_SLOTS = 6
#: an assignment held for fewer slots than this is a lag, not a swap (:func:`slot_assignments`)
MIN_RUN = 4
#: a swap's ``margin`` (nats) beyond which the model tells truth from the exchange: a factor 3
DECIDES = math.log(3.0)
#: the pseudo-tracker of :func:`model_floor` and its number of random tie-breaks per seed
FLOOR = "model-ties"
FLOOR_DRAWS = 20

SWAPS = pl.Schema(
    {
        "seed": pl.Int64,
        "tracker": pl.String,
        "slot": pl.Int64,
        "users": pl.String,
        "true_nodes": pl.String,
        "track_nodes": pl.String,
        "meet": pl.Boolean,
        "kind": pl.String,
        "event": pl.Boolean,
        "cpda_tie": pl.Boolean,
        "cpda": pl.String,
        "margin": pl.Float64,
        "model": pl.String,
    }
)
RESULTS = pl.Schema(
    {
        "seed": pl.Int64,
        "tracker": pl.String,
        "hop_error": pl.Float64,
        "slot_error": pl.Float64,
        "swaps": pl.Int64,
    }
)


def simulate(seed: int, *, duration: float = DURATION, users: int = USERS, drop: float = DROP, walk: str = "routes"):
    """The hallway dataset of one seed (``onebit simulate hallway``), read back as the pipeline
    reads it: site (with ``targets``), motion, truth."""
    with tempfile.TemporaryDirectory(prefix="onebit-fh-diagnose-") as tmp:
        data = write_hallway_dataset(
            Path(tmp) / "data", seed=seed, duration=duration, users=users, drop=drop, walk=walk
        )
        site = load_site(data / "site.toml")
        motion = read_motion_csv(data / "motion.csv", [m.id for m in site.motion_sensors]).motion
        truth = pl.read_csv(data / "truth.csv").select("t", "target", "x", "y")
    return site, motion, truth


def slot_truth(truth: pl.DataFrame, site: Site, t0: float, period: float, d: int) -> tuple[list[str], np.ndarray]:
    """(targets, (V, D) true node index per slot, -1 when absent): the truth sample nearest each
    slot's mid time (within half a slot), its node as the scorer computes it."""
    nodes = site.sensor_graph.nodes
    idx = {n: i for i, n in enumerate(nodes)}
    tr = truth_nodes(truth, site).drop_nulls("node")
    targets = sorted(tr["target"].unique().to_list())
    grid = pl.DataFrame({"t": t0 + (np.arange(d) + 0.5) * period, "slot": np.arange(d)})
    out = np.full((len(targets), d), -1, dtype=np.int64)
    for v, tgt in enumerate(targets):
        one = tr.filter(pl.col("target") == tgt).sort("t").select("t", "node")
        j = grid.join_asof(one, on="t", strategy="nearest", tolerance=period / 2 + 1e-9)
        ok = j["node"].is_not_null().to_numpy()
        out[v, j["slot"].to_numpy()[ok]] = [idx[n] for n in j["node"].to_numpy()[ok]]
    return targets, out


def track_paths(tracks: pl.DataFrame, nodes, t0: float, period: float, d: int) -> tuple[list[str], np.ndarray]:
    """(track names, (U, D) node index per slot, -1 when absent) of a TRACKS table."""
    idx = {n: i for i, n in enumerate(nodes)}
    names = sorted(tracks["track"].unique().to_list())
    out = np.full((len(names), d), -1, dtype=np.int64)
    s = np.rint((tracks["t"].to_numpy() - t0) / period - 0.5).astype(np.int64)
    u = np.array([names.index(x) for x in tracks["track"].to_list()], dtype=np.int64)
    k = np.array([idx[n] for n in tracks["node"].to_list()], dtype=np.int64)
    ok = (s >= 0) & (s < d)
    out[u[ok], s[ok]] = k[ok]
    return names, out


def slot_assignments(true: np.ndarray, est: np.ndarray, hops: np.ndarray, miss: int) -> np.ndarray:
    """(D, V) decoded track followed by each true user per slot (module docstring): per slot
    the minimum-hop matching, the previous slot's one kept among equals; then a run of fewer
    than :data:`MIN_RUN` slots (a track a slot behind its user while two users pass each
    other, not a change of identity) takes the assignment of the run before it."""
    v, d = true.shape
    u = est.shape[0]
    out = np.full((d, v), -1, dtype=np.int64)
    prev = None
    for s in range(d):  # sequential: each slot's tie-break depends on the previous slot
        tn, en = true[:, s], est[:, s]
        cost = np.where(
            (tn[:, None] >= 0) & (en[None, :] >= 0), hops[np.maximum(tn, 0)[:, None], np.maximum(en, 0)[None, :]], miss
        )
        cost = np.where(tn[:, None] >= 0, cost, 0).astype(float)
        if prev is not None:
            cost = cost - 1e-3 * (np.arange(u)[None, :] == prev[:, None])
        r, c = _optimize.linear_sum_assignment(cost)
        a = np.full(v, -1, dtype=np.int64)
        a[r] = c
        out[s] = a
        prev = a
    change = np.flatnonzero((out[1:] != out[:-1]).any(axis=1)) + 1
    starts = np.concatenate([[0], change, [d]])
    for a, b in zip(starts[1:-1], starts[2:]):  # sequential: a short run takes the run before it
        if b - a < MIN_RUN:
            out[a:b] = out[a - 1]
    return out


def meeting_kind(true: np.ndarray, users: tuple[int, int], slot: int, hops: np.ndarray) -> tuple[bool, str]:
    """Whether true users ``users`` met (within 1 hop) near ``slot`` and how (module docstring)."""
    a, b = users
    d = true.shape[1]
    lo, hi = max(0, slot - MEET_SLOTS), min(d, slot + MEET_SLOTS + 1)
    ta, tb = true[a], true[b]
    both = (ta >= 0) & (tb >= 0)
    near = both & (hops[np.maximum(ta, 0), np.maximum(tb, 0)] <= 1)
    win = np.flatnonzero(near[lo:hi]) + lo
    if win.size == 0:
        return False, "none"
    s0, s1 = int(win[0]), int(win[-1])
    while s0 > 0 and near[s0 - 1]:
        s0 -= 1
    while s1 < d - 1 and near[s1 + 1]:
        s1 += 1

    def other(row, start, step):
        here = row[start]
        k = start
        while 0 <= k < d and (row[k] == here or row[k] < 0):
            k += step
        return int(row[k]) if 0 <= k < d else -1

    # walked the same edges the same way (co-walk), or against each other (crossing), near the swap
    w0, w1 = max(0, slot - KIND_SLOTS), min(d, slot + KIND_SLOTS + 1)
    ea, eb = _moves(ta[w0:w1]), _moves(tb[w0:w1])
    same, opposite = len(ea & eb), len(ea & {(y, x) for x, y in eb})
    if same or opposite:
        return True, "co-walk" if same >= opposite else "crossing"
    s0, s1 = max(s0, w0), min(s1, w1 - 1)
    in_a, in_b = other(ta, s0, -1), other(tb, s0, -1)
    out_a, out_b = other(ta, s1, 1), other(tb, s1, 1)
    same_in = in_a == in_b or in_a < 0 or in_b < 0
    same_out = out_a == out_b or out_a < 0 or out_b < 0
    kind = {(False, False): "crossing", (True, False): "same-in", (False, True): "same-out", (True, True): "co-walk"}[
        (same_in, same_out)
    ]
    return True, kind


def _moves(row: np.ndarray) -> set[tuple[int, int]]:
    """Directed node changes ``(from, to)`` of a true path piece."""
    r = row[row >= 0]
    step = np.flatnonzero(r[1:] != r[:-1])
    return {(int(r[k]), int(r[k + 1])) for k in step}


def diagnose_seed(job: tuple[int, float, int, float, str]) -> tuple[list[dict], list[dict]]:
    """A task: one seed, every tracker; (result rows, swap rows)."""
    seed, duration, users, drop, walk = job
    site, motion, truth = simulate(seed, duration=duration, users=users, drop=drop, walk=walk)
    g = site.sensor_graph
    nodes = g.nodes
    hops = hop_matrix(nodes, g.edges)
    diameter = int(hops[hops <= len(nodes)].max())
    by_name = {e.name: e for e in ENTRIES}
    results, swaps = [], []
    inputs = {"motion": motion}
    # in the order that lets trackers of one decode share it (hmm2's with findinghumo-flow's,
    # :func:`onebit.models.graph_hmm.decoding.decode_motion`), as a pipeline run does
    outs = {name: by_name[name].spec.run(inputs, site, by_name[name].spec.config()) for name in _SHARING_ORDER}
    for name in TRACKERS:
        spec = by_name[name].spec
        out = outs[name]
        rows, _ = score(name, {f"{name}_tracks": out["tracks"], "truth": truth}, site)
        hop = next(v for tr, m, v, _ in rows if m == "hop_error")
        art = out["artifacts"]
        t0, period, d = art["t0"], art["period"], art["active"].shape[0]
        targets, true = slot_truth(truth, site, t0, period, d)
        _, est = track_paths(out["tracks"], nodes, t0, period, d)
        assign = slot_assignments(true, est, hops, diameter)
        hmm_paths = art.get("decoded_paths", art["paths"])
        feature = np.isin(np.asarray(nodes), list(g.entries) + list(g.exits))
        events = colocation_events(hmm_paths, feature, hops)
        decisions = out.get("cpda")
        cfg = spec.config()
        p_hit, p_false = getattr(cfg, "p_hit", 0.9), getattr(cfg, "p_false", 0.05)
        n_swaps = 0
        for s in range(1, d):
            changed = np.flatnonzero((assign[s] != assign[s - 1]) & (true[:, s] >= 0) & (true[:, s - 1] >= 0))
            if changed.size < 2:
                continue
            n_swaps += 1
            pair = (int(changed[0]), int(changed[1]))
            meet, kind = meeting_kind(true, pair, s, hops)
            tracks_before = {int(assign[s - 1][v]) for v in changed}
            ev = [c for c, grp in events if abs(c - s) <= MEET_SLOTS and len(tracks_before & set(grp)) >= 2]
            cand = [
                e
                for e in range(max(1, s - 2 * MEET_SLOTS), min(d, s + MEET_SLOTS + 1))
                if (true[list(pair), e] >= 0).all()
            ]
            margin, _ = exchange_margin(
                true, pair[0], pair[1], cand, art["active"], art["eatg"], p_hit=p_hit, p_false=p_false
            )
            swaps.append(
                {
                    "seed": seed,
                    "tracker": name,
                    "slot": s,
                    "users": " ".join(targets[v] for v in changed),
                    "true_nodes": " ".join(nodes[true[v, s]] for v in changed),
                    "track_nodes": " ".join(
                        nodes[est[assign[s - 1][v], s]] if est[assign[s - 1][v], s] >= 0 else "-" for v in changed
                    ),
                    "meet": meet,
                    "kind": kind,
                    "event": bool(ev),
                    "cpda_tie": _cpda_tie(decisions, s),
                    "cpda": _cpda_at(decisions, s),
                    "margin": margin,
                    "model": model_verdict(margin),
                }
            )
        results.append(
            {
                "seed": seed,
                "tracker": name,
                "hop_error": float(hop),
                "slot_error": slot_error(true, est, hops, diameter),
                "swaps": n_swaps,
            }
        )
    results.append(model_floor(seed, site, truth, true, art, p_hit, p_false))
    return results, swaps


def model_floor(
    seed: int, site: Site, truth: pl.DataFrame, true: np.ndarray, art: dict, p_hit: float, p_false: float
) -> dict:
    """The ``model-ties`` row: the hop error of the *true* slot paths relabelled at every
    co-location by the most probable pairing under the decoders' model, exact ties broken by
    chance (:func:`onebit.models.graph_hmm.likelihood.tie_relabelling`), mean over
    :data:`FLOOR_DRAWS` draws (seeded by the seed). Positions are exact; what remains is the
    identity error no maximiser of that model can avoid on these observations."""
    rng = np.random.default_rng(seed)
    nodes = site.sensor_graph.nodes
    errs, changed = [], []
    for _ in range(FLOOR_DRAWS):
        x, c = tie_relabelling(true, art["active"], art["eatg"], p_hit=p_hit, p_false=p_false, rng=rng)
        tracks = tracks_table(FLOOR, x, nodes, site, art["t0"], art["period"])
        rows, _ = score(FLOOR, {f"{FLOOR}_tracks": tracks, "truth": truth}, site)
        errs.append(next(v for _, m, v, _ in rows if m == "hop_error"))
        changed.append(c)
    return {
        "seed": seed,
        "tracker": FLOOR,
        "hop_error": float(np.mean(errs)),
        "slot_error": 0.0,
        "swaps": int(round(np.mean(changed))),
    }


def model_verdict(margin: float) -> str:
    """``truth``: the decoders' model prefers the true labelling to every exchange of the two
    users' tails near the swap by more than :data:`DECIDES` (a better search could fix the
    swap); ``tie``: within that factor -- the model cannot tell who is who, so no decoder,
    CPDA or association maximising it can be relied on there; ``swap``: the model prefers the
    exchange (it is wrong there); ``impossible``: the true paths have probability 0 under it."""
    if not np.isfinite(margin) and margin < 0:
        return "impossible"
    return "truth" if margin > DECIDES else "swap" if margin < -DECIDES else "tie"


def slot_error(true: np.ndarray, est: np.ndarray, hops: np.ndarray, miss: int) -> float:
    """Identity-free error: mean over (slot, present user) of the hop error under the best
    matching of that slot alone -- what these decoded positions would score if every identity
    were right; no relabelling of the tracks can score below it."""
    tot, n = 0.0, 0
    for s in range(true.shape[1]):  # one tiny assignment per slot
        tn = true[:, s][true[:, s] >= 0]
        if tn.size == 0:
            continue
        en = est[:, s]
        cost = np.where(en[None, :] >= 0, hops[tn[:, None], np.maximum(en, 0)[None, :]], miss).astype(float)
        r, c = _optimize.linear_sum_assignment(cost)
        tot += float(cost[r, c].sum()) + miss * (tn.size - r.size)
        n += tn.size
    return tot / n if n else 0.0


def _cpda_tie(decisions: pl.DataFrame | None, slot: int) -> bool | None:
    """Whether a CPDA decision within ``MEET_SLOTS`` of ``slot`` (last pass) had another pairing
    as probable as keeping the HMM's (within 0.02): a'' cannot choose there."""
    if decisions is None:
        return None
    near = decisions.filter((pl.col("slot") - slot).abs() <= MEET_SLOTS, pl.col("pass") == pl.col("pass").max())
    for keep, alts in near.select("p_keep", "alternatives").iter_rows():
        probs = [float(a.rsplit(":", 1)[1]) for a in alts.split("; ")][1:]  # the identity is listed first
        if any(abs(p - keep) < 0.02 for p in probs):
            return True
    return False


def _cpda_at(decisions: pl.DataFrame | None, slot: int) -> str:
    """What CPDA decided within ``MEET_SLOTS`` of ``slot`` (last pass): ``switch``/``keep`` with
    the posteriors of the chosen and of the HMM's pairing; ``-`` when it saw no event."""
    if decisions is None or decisions.height == 0:
        return "-"
    near = decisions.filter((pl.col("slot") - slot).abs() <= MEET_SLOTS, pl.col("pass") == pl.col("pass").max())
    if near.height == 0:
        return "-"
    return "; ".join(
        f"{'switch' if sw else 'keep'}@{sl} at {nd} p={pc:.2f} keep={pk:.2f}"
        for sl, nd, sw, pc, pk in near.select("slot", "node", "switched", "p_chosen", "p_keep").iter_rows()
    )


def summarise(results: pl.DataFrame, swaps: pl.DataFrame) -> pl.DataFrame:
    kinds = ("crossing", "same-in", "same-out", "co-walk", "none")
    per = swaps.group_by("tracker").agg(
        *(pl.col("kind").eq(k).sum().cast(pl.Int64).alias(k) for k in kinds),
        at_event=pl.col("event").sum().cast(pl.Int64),
        cpda_tie=pl.col("cpda_tie").sum().cast(pl.Int64),
        **{f"model_{k}": pl.col("model").eq(k).sum().cast(pl.Int64) for k in ("truth", "tie", "swap", "impossible")},
    )
    return (
        results.group_by("tracker", maintain_order=True)
        .agg(
            seeds=pl.len().cast(pl.Int64),
            hop_error=pl.col("hop_error").mean(),
            hop_error_sd=pl.col("hop_error").std(),
            slot_error=pl.col("slot_error").mean(),
            swaps=pl.col("swaps").sum(),
        )
        .join(per, on="tracker", how="left")
        .fill_null(0)
    )


#: trackers whose every swap is listed in ``diagnosis.md`` (the issue's table)
LISTED = ("hmm2", "findinghumo", "findinghumo-flow")


def markdown_table(df: pl.DataFrame) -> str:
    """A polars frame as a Markdown table (floats to 3 decimals)."""
    cells = [
        [f"{v:.3f}" if isinstance(v, float) else ("" if v is None else str(v)) for v in row] for row in df.iter_rows()
    ]
    lines = ["| " + " | ".join(df.columns) + " |", "|" + " --- |" * len(df.columns)]
    lines += ["| " + " | ".join(c.replace("|", "/") for c in row) + " |" for row in cells]
    return "\n".join(lines) + "\n"


def markdown(summary: pl.DataFrame, swaps: pl.DataFrame, *, seeds: tuple[int, int], duration: float) -> str:
    """``diagnosis.md``: the summary and every swap of the :data:`LISTED` trackers."""
    head = (
        f"Seeds {seeds[0]}-{seeds[1]}, hallway, {USERS} users, {duration:g} s, drop {DROP}; "
        "written by `onebit experiment findinghumo-diagnose OUT` (onebit/experiments/findinghumo_diagnose.py).\n\n"
    )
    listed = swaps.filter(pl.col("tracker").is_in(LISTED)).sort("tracker", "seed", "slot")
    return head + markdown_table(summary) + "\n" + markdown_table(listed)


def run(
    out: Path,
    *,
    seed: int = 0,
    trials: int | None = None,
    quick: bool = False,
    echo=print,
    executor: Executor | None = None,
    walk: str = "routes",
) -> Path:
    """The registered entry point (see :mod:`onebit.experiments`); ``quick``: 2 seeds of 60 s."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    n = trials or (2 if quick else SEEDS)
    duration = 60.0 if quick else DURATION
    jobs = [(seed + k, duration, USERS, DROP, walk) for k in range(n)]
    per_seed, timings = run_trials(
        diagnose_seed, jobs, executor=executor, label=lambda j: f"seed {j[0]}", echo=echo, study="findinghumo-diagnose"
    )
    results = pl.DataFrame([r for rs, _ in per_seed for r in rs], schema=RESULTS)
    swaps = pl.DataFrame([w for _, ws in per_seed for w in ws], schema=SWAPS)
    summary = summarise(results, swaps)
    writers.write_csv(results, out / "results.csv")
    writers.write_csv(swaps, out / "swaps.csv")
    writers.write_csv(summary, out / "summary.csv")
    writers.write_text(markdown(summary, swaps, seeds=(seed, seed + n - 1), duration=duration), out / "diagnosis.md")
    write_timings(timings, out)
    echo(format_table(summary))
    return out
