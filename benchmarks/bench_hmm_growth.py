"""hmm1 / hmm2 / Adaptive-HMM decoder time per slot against the size of the sensor graph, at
the same activity (#24 item 4).

``python -m benchmarks.bench_hmm_growth [--scenario hallway|home] [--minutes M] [--sizes 25,50,100,200]
[--modes full2,full1,adaptive] [--no-reference]``. The activity is a simulator's, slotted as the
trackers slot it (1 s, mid-slot sampling): the ``hallway`` (FindingHuMo Fig. 1 floor, 20 PIRs,
3 users walking all the time; the default) or the ``home`` (``onebit simulate home``: 50 PIRs,
2 residents, ``M`` minutes from hour ``H`` of the day, ``--start-hour H``). The graph grows by a
wing of silent sensors (a grid corridor of rows of 10, joined to the graph's last node) to ``N``
nodes, so every size decodes exactly the same motion and only the building grows. The decoder
is the trackers' (:class:`~onebit.models.graph_hmm.adaptive.WindowDecoder`, modes ``full2`` =
hmm2, ``full1`` = hmm1, ``adaptive`` = findinghumo's windows, ``joint`` = findinghumo's joint
re-decoding of meetings on the windows' paths (``joint2``: with ``joint_hops = 2``), its reference every meeting on every node; the trackers' defaults, the site's
targets as the user bound, the EATG trained on the activity); the CPU time per slot (the
fastest of ``--repeat`` runs) excludes the once-per-run model set-up (on its own row). The
paths decoded on every ``N`` are compared with the smallest graph's (printed; equal unless the
wing changes the trained model of the node it joins, as on the home, where residents use that
node), and on the smallest ``N`` checked equal to the numpy reference's
(``DecoderParams(compiled=False)``: every user decoded on every state; ``--no-reference`` skips
it on long logs). Rows go to ``benchmarks/results.csv`` with the growth exponent over the sizes
(:mod:`benchmarks.results`; 0 = independent of ``N``).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.results import Result, Table


def activity(scenario: str, minutes: float, start_hour: float, seed: int = 7):
    """``(active (D, n) bool, nodes, edges, signatures, targets)`` of a simulated log: the
    ``hallway`` (FindingHuMo Fig. 1 floor, 20 PIRs, 3 users walking all the time) or the
    ``home`` (50 PIRs, 2 residents, ``minutes`` from ``start_hour`` of its day)."""
    import polars as pl

    from onebit.core.site import load_site
    from onebit.models.graph_hmm.decoding import door_signatures, slot_activity

    t0 = 0.0
    if scenario == "hallway":
        from onebit.datasets.builtin import builtin_site_path
        from onebit.datasets.hallway_sim import HallwaySimConfig, simulate_hallway

        site = load_site(builtin_site_path("hallway"))
        sim = simulate_hallway(site, HallwaySimConfig(duration=minutes * 60.0, users=3), seed=seed)
        targets = 3
    else:
        from onebit.datasets.home_sim import HomeSimConfig, simulate_home, site_toml

        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "site.toml"
            path.write_text(site_toml(2))
            site = load_site(path)
        t0 = start_hour * 3600.0
        sim = simulate_home(site, HomeSimConfig(duration=t0 + minutes * 60.0, residents=2), seed=seed)
        targets = 2
    g = site.sensor_graph
    motion = sim.toggles.filter(pl.col("t") >= t0).select("t", "sensor", on=pl.col("value") > 0)
    active, _ = slot_activity(motion, g.nodes, 1.0, "mid")
    return active, tuple(g.nodes), [tuple(e) for e in g.edges], door_signatures(g), targets


def grown(nodes, edges, n_total: int):
    """The graph with a silent wing: ``n_total - len(nodes)`` nodes in rows of 10 (a grid), its
    first node joined to the graph's last node."""
    import networkx as nx

    extra = n_total - len(nodes)
    if extra <= 0:
        return tuple(nodes), list(edges)
    cols = min(10, extra)
    g = nx.grid_2d_graph((extra + cols - 1) // cols, cols)
    wing = [f"W{r:03d}_{c}" for r, c in sorted(g.nodes)][:extra]
    keep = set(wing)
    w_edges = [(f"W{a[0]:03d}_{a[1]}", f"W{b[0]:03d}_{b[1]}") for a, b in g.edges]
    w_edges = [(a, b) for a, b in w_edges if a in keep and b in keep]
    return tuple(nodes) + tuple(wing), list(edges) + w_edges + [(nodes[-1], wing[0])]


def decode_timed(active, nodes, edges, sigs, mode: str, *, targets: int = 2, compiled: bool = True):
    """``(set-up s, decode s, paths)`` of one decoder run (the trackers' default parameters)."""
    from onebit.models.graph_hmm.adaptive import DecoderParams, WindowDecoder
    from onebit.models.graph_hmm.eatg import hop_matrix, trained_eatg

    hops = hop_matrix(nodes, edges)
    eatg = trained_eatg(active, nodes, hops, horizon=5)
    idx = {n: i for i, n in enumerate(nodes)}
    sig_idx = [(idx[a], idx[b]) for a, b in sigs]
    params = DecoderParams(mode=mode, max_users=targets, compiled=compiled)
    t0 = time.process_time()
    dec = WindowDecoder(eatg, len(nodes), signatures=sig_idx, params=params)
    t1 = time.process_time()
    dec.extend(active)
    dec.advance(final=True)
    t2 = time.process_time()
    return t1 - t0, t2 - t1, dec.result().paths


def joint_timed(active, nodes, edges, sigs, mode: str, *, targets: int = 2, compiled: bool = True):
    """``(set-up s, joint s, paths)``: findinghumo's joint re-decoding of meetings
    (:func:`~onebit.models.graph_hmm.joint.redecode_meetings`, the trackers' defaults) on the
    Adaptive-HMM's paths (not timed); set-up: its :class:`~onebit.models.graph_hmm.joint.JointSpaces`
    (once per run); ``compiled=False``: every meeting on every node, its reference here."""
    from onebit.models.graph_hmm.decoding import HmmConfig
    from onebit.models.graph_hmm.eatg import hop_matrix, trained_eatg
    from onebit.models.graph_hmm.joint import JointSpaces, redecode_meetings

    cfg = HmmConfig()
    _, _, paths = decode_timed(active, nodes, edges, sigs, "adaptive", targets=targets)
    eatg = trained_eatg(active, nodes, hop_matrix(nodes, edges), horizon=5)
    t0 = time.process_time()
    reach = int(mode[len("joint") :] or cfg.joint_hops)  # joint2: the paper's 2-hop neighbourhood
    spaces = JointSpaces(eatg, reach, whole=not compiled)
    t1 = time.process_time()
    out, _ = redecode_meetings(
        paths,
        active,
        eatg,
        p_hit=cfg.p_hit,
        p_false=cfg.p_false,
        pad=cfg.joint_pad,
        spaces=spaces,
    )
    return t1 - t0, time.process_time() - t1, out


def growth(sizes, values) -> float | None:
    """The growth exponent over the sizes (``None`` for a single size)."""
    if len(sizes) < 2 or sizes[-1] == sizes[0]:
        return None
    return float(np.log(values[-1] / values[0]) / np.log(sizes[-1] / sizes[0]))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--scenario", choices=("hallway", "home"), default="hallway", help="simulated log (default hallway)"
    )
    ap.add_argument("--minutes", type=float, default=10.0, help="minutes simulated (default 10)")
    ap.add_argument("--start-hour", type=float, default=8.0, help="hour of the day it starts at (default 8)")
    ap.add_argument("--sizes", default="25,50,100,200", help="graph sizes N (default 25,50,100,200)")
    ap.add_argument("--modes", default="full2,full1", help="decoder modes (full2 = hmm2, full1 = hmm1)")
    ap.add_argument("--repeat", type=int, default=3, help="runs per size, the fastest kept (default 3)")
    ap.add_argument(
        "--no-reference",
        dest="reference",
        action="store_false",
        help="skip the numpy reference on the smallest graph (slow on long logs)",
    )
    ap.add_argument("--no-write", action="store_true", help="print only, do not update results.csv")
    args = ap.parse_args(argv)
    from onebit.models.graph_hmm import ascent

    sizes = [int(s) for s in args.sizes.split(",")]
    active, nodes, edges, sigs, targets = activity(args.scenario, args.minutes, args.start_hour)
    n_slots = active.shape[0]
    what = f"{args.scenario} sim {args.minutes:g} min" + (
        f" from {args.start_hour:g} h" if args.scenario == "home" else ""
    )
    print(f"{what}: {n_slots} slots, {int(active.sum())} active (slot, node) cells, {len(nodes)} nodes")
    # warm the kernels (compile or load from the cache) outside the timing
    timed = {"joint": joint_timed, "joint2": joint_timed}
    for mode in args.modes.split(","):
        timed.get(mode, decode_timed)(active[:60], nodes, edges, sigs, mode, targets=targets)
    table = Table()
    for mode in args.modes.split(","):
        name = {
            "full2": "hmm2",
            "full1": "hmm1",
            "adaptive": "findinghumo-windows",
            "joint": "findinghumo-joint",
            "joint2": "findinghumo-joint (joint_hops 2)",
        }.get(mode, mode)
        run = timed.get(mode, decode_timed)
        per_slot, setups, ref = [], [], None
        for n in sizes:
            g_nodes, g_edges = grown(nodes, edges, n)
            act = np.zeros((n_slots, len(g_nodes)), bool)
            act[:, : len(nodes)] = active
            before = ascent.DECODE_STATS.copy()
            runs = [run(act, g_nodes, g_edges, sigs, mode, targets=targets) for _ in range(args.repeat)]
            stats = (ascent.DECODE_STATS - before) // args.repeat
            setup, dt, paths = min(r[0] for r in runs), min(r[1] for r in runs), runs[0][2]
            if ref is None and not args.reference:
                ref = paths
            if ref is None:
                ref = run(act, g_nodes, g_edges, sigs, mode, targets=targets, compiled=False)[2]
                if not np.array_equal(paths, ref):
                    raise AssertionError(f"{name}: the paths differ from the numpy reference's on N={n}")
            same = paths.shape == ref.shape and np.array_equal(paths, ref)
            per_slot.append(dt / n_slots)
            setups.append(setup)
            print(
                f"{name} N={len(g_nodes):>4}: {dt / n_slots * 1e3:8.3f} ms/slot ({dt:.2f} s), set-up {setup:.3f} s,"
                f" paths {'equal' if same else 'DIFFER'} to N={sizes[0]}'s"
                + (
                    f"; {stats[0]} user decodes, {stats[1]} on all states ({stats[2]} uncertified)"
                    if not mode.startswith("joint")
                    else ""
                ),
                flush=True,
            )
        g = growth(sizes, per_slot)
        for n, v in zip(sizes, per_slot):
            table.add(
                Result(
                    f"{name} per-slot cost vs graph size",
                    f"{name} decoder, {what} + silent wing, ms per slot",
                    n,
                    "ms cpu per slot",
                    v * 1e3,
                    peer=per_slot[0] * 1e3,
                    peer_name=f"the same activity on N={sizes[0]}",
                    growth=g if n == sizes[-1] else None,
                    goal="independent of N (growth ~0)",
                    met=(abs(g) < 0.25) if n == sizes[-1] and g is not None else None,
                )
            )
        gs = growth(sizes, setups)
        table.add(
            Result(
                f"{name} per-slot cost vs graph size",
                f"{name} decoder set-up (full-state model, once per run), {what}, s",
                sizes[-1],
                "s",
                setups[-1],
                peer=setups[0],
                peer_name=f"N={sizes[0]}",
                growth=gs,
                goal="once per run",
            )
        )
    if not args.no_write:
        print(f"wrote {table.write()}")


if __name__ == "__main__":
    main()
