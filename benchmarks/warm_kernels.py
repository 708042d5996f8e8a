"""Compile every numba kernel once, with the argument types the pipeline uses, so numba's
on-disk cache (``cache=True``) holds them: ``make install`` runs this, and a run (``make demo``,
``onebit run``) then loads compiled code in milliseconds instead of compiling on its critical
path. Prints the time each kernel module took (cold: compiled; warm: loaded from the cache).

Run with ``python -m benchmarks.warm_kernels``.
"""

from __future__ import annotations

import time

import numpy as np
import polars as pl
import shapely


def findinghumo() -> None:
    from onebit.models.graph_hmm.adaptive import DecoderParams, decode_run
    from onebit.models.graph_hmm.eatg import hop_matrix, layout_eatg

    nodes = ("a", "b", "c", "d")
    eatg = layout_eatg(nodes, hop_matrix(nodes, (("a", "b"), ("b", "c"), ("c", "d"))))
    act = np.eye(4, dtype=bool)[[0, 1, 2, 3, 2, 1]] | np.eye(4, dtype=bool)[[3, 3, 0, 0, 0, 0]]
    for mode in ("adaptive", "full1", "full2"):
        decode_run(act, eatg, params=DecoderParams(mode=mode, d_max=3, tau=2))
    from onebit.models.graph_hmm.joint import redecode_meetings

    redecode_meetings(np.array([[0, 1, 2, 2], [2, 2, 1, 0]]), act[:4], eatg, p_hit=0.9, p_false=0.05, pad=1)
    from onebit.models.graph_hmm.decoding import cap_users

    cap_users(np.array([[0, 1, 2, 2], [2, 2, 1, 0], [3, 3, -1, -1]]), act[:4], eatg.hops, 2)


def scoring() -> None:
    from onebit.scoring.mot import mot_metrics

    obj = pl.DataFrame({"t": [0.0, 0.0, 1.0], "target": ["a", "b", "a"]})
    hyp = pl.DataFrame({"t": [0.0, 1.0, 1.0], "track": ["k", "k", "l"]})
    dist = pl.DataFrame(
        {
            "t": [0.0, 0.0, 1.0, 1.0],
            "target": ["a", "b", "a", "a"],
            "track": ["k", "k", "k", "l"],
            "distance": [0.2] * 4,
        }
    )
    mot_metrics(obj, hyp, dist, gate=1.0)


def intruder() -> None:
    from onebit.models.motion import Motion, Room
    from onebit.models.pir import Deployment, WorldGrid
    from onebit.trackers.intruder.filter import run_filter

    q = np.zeros((2, 4, 4))
    q[0, :2, :2] = q[1, 2:, 2:] = 0.8
    dep = Deployment(
        ("s0", "s1"),
        WorldGrid(0.0, 0.0, 1.0, 4, 4),
        q,
        np.zeros(2),
        np.full(2, 1e-6),
        np.zeros(2),
        np.array([4, 4]),
        (),
    )
    fired = np.array([[True, False], [False, True]])
    motion = Motion(2.0, 4.0, 1.5, 4.0, 50)
    for room in (
        Room(shapely.box(0, 0, 4, 4)),
        Room(shapely.box(0, 0, 4, 4).difference(shapely.box(1.5, 1.5, 2.5, 2.5))),
    ):
        for resample in ("systematic", "multinomial"):
            run_filter(
                fired,
                ~fired,
                dep,
                room,
                motion,
                n_particles=20,
                half_w=1.0,
                half_d=1.0,
                rng=np.random.default_rng(0),
                resample=resample,
                log_particles=5,
                compiled=True,
            )


def beams() -> None:
    from onebit.trackers.beams.assignment import Constraints, assign_agents
    from onebit.trackers.beams.counting import RegionEdges, correct

    src, tgt = np.array([0, 1, 2, 1]), np.array([1, 2, 1, 0])
    assign_agents(src, tgt, 3, compiled=True)
    assign_agents(
        src,
        tgt,
        3,
        constraints=Constraints(max_track_length=9, min_traversal=np.full(3, 0.5)),
        times=np.arange(4.0),
        compiled=True,
    )
    edges = RegionEdges.from_arrays([0, 1, 1, 2], [1, 0, 2, 1], 3)
    correct(np.array([1, 2]), np.array([2, 1]), edges, n_agents=1, compiled=True)


def clustertrack() -> None:
    from onebit.trackers.clustertrack import kernels
    from onebit.trackers.clustertrack.algorithm import scan_clusters

    for dim in (1, 2):
        x = np.random.default_rng(0).random((6, dim))
        scan_clusters(
            np.arange(6.0),
            np.repeat(np.arange(2), 3),
            x,
            np.zeros((2, 2)),
            2,
            H=2,
            K=4,
            L=6,
            D0=0.5,
            rng=np.random.default_rng(0),
            compiled=True,
        )
        kernels.candidate_costs(x, x[:2], x[:2], np.zeros(2), 3, True)
        kernels.summed_distances(np.zeros((2, 2)), np.arange(2), x[:2])
        # the pass's fused scan (types as cluster_track passes them)
        kernels.scan_step(np.arange(6.0), np.arange(6), x, 3, np.zeros((2, 2)), 2.0, 2, 4, 0.5, 2, 1.0)
    kernels.map_intervals(np.random.default_rng(0).random(5), np.array([[0.0, 1.0], [2.0, 3.0]]), 2.0)
    kernels.jitter_cells(np.zeros((2, 2)), np.zeros(3, dtype=np.int64), np.zeros((3, 2)), 0.1)
    key = np.random.default_rng(0).random(8)
    kernels.ordered_prefix(key, 3)  # the scan order's sorted start (large scans)
    kernels.kth_smallest(key, 2)


def binpf() -> None:
    from onebit.trackers.binpf import kernels

    rng = np.random.default_rng(0)
    x = rng.random((2, 5, 4))
    sensors, radii = np.array([[0.0, 0.0], [1.0, 0.0]]), np.ones(2)
    on = np.array([[True, False]])
    _, _, d = kernels.observation_update(x, np.full(2, 0.5), on[0], sensors, radii, 0.75, 0.01, 0.3, 0.3)
    kernels.resampled_mean(d, np.zeros((2, 5), dtype=np.int64))
    _, _, d, near = kernels.observation_update_local(
        x, np.full(2, 0.5), on[0], sensors, radii, 0.75, 0.01, 0.3, 0.3, np.empty((2, 2, 5))
    )
    kernels.resampled_mean_near(d, np.zeros((2, 5), dtype=np.int64), near)
    idx = kernels.systematic_resample(np.zeros((2, 5)), rng.random((2, 1)))
    kernels.gather_particles(x, np.zeros((2, 5, 5, 2)), idx)
    y = rng.uniform(-5.0, 5.0, 7)
    kernels.exp_into(y, np.empty_like(y), np.empty(y.size, dtype=np.int64))


def binpf_runs() -> None:
    """The compiled frame loop (``kernels.run_frames`` and what it calls) as runs reach it: the
    batch filter (from ``COMPILED_MIN_FRAMES`` frames on) and the online driver (``commit_lag``,
    what ``onebit follow`` runs), with the stage's own argument types."""
    import tempfile
    from pathlib import Path

    from onebit.datasets.catalogue import get_scenario
    from onebit.pipeline.runner import run_pipeline
    from onebit.trackers.binpf.filter import COMPILED_MIN_FRAMES

    with tempfile.TemporaryDirectory(prefix="onebit-warm-") as tmp:
        data = get_scenario("proximity-grid").write(
            Path(tmp) / "d",
            seed=0,
            duration=float(COMPILED_MIN_FRAMES + 10),
            agents=None,
            drop=0.0,
            camera=False,
            params={},
        )
        for lag in (0, 5):
            config = {"binpf": {"particles": 20, "commit_lag": lag, "log_particles": 2}}
            run_pipeline(data, Path(tmp) / f"run{lag}", trackers=("binpf",), config=config, rrd=False, progress=False)


def simulators() -> None:
    """A PIR's refractory time in ``onebit simulate from-truth``, and the second-order Viterbi
    decoders (their compiled forms, as the graph HMM tests call them)."""
    from onebit.datasets import kernels
    from onebit.models.graph_hmm import kernels as hmm

    runs = np.array([[0, 0, 1], [0, 5, 2], [3, 9, 6]], dtype=np.int64)
    kernels.pir_refractory(runs[0], runs[1], runs[2], np.arange(10.0), np.array([1.0, 0.0]), 0.5)
    s = 3
    lp = np.log(np.full(s, 1 / s))
    b = np.log(np.full((4, s), 0.5))
    hmm.viterbi_second_order(lp, np.log(np.full((s, s), 1 / s)), np.log(np.full((s, s, s), 1 / s)), b)
    log_stay, log_move = np.log(np.full(s, 0.5)), np.log(np.full((s, s, s), 0.25))
    hmm._viterbi_motion2(lp, log_stay, log_move, b)
    hmm._viterbi_motion2_sparse(lp, log_stay, log_move, b, *hmm.move_support(log_move))


def homes() -> None:
    """The count model's Viterbi and the known residents' turns (compiled when numba is loaded)."""
    from onebit.models.occupancy import _viterbi_kernel
    from onebit.trackers.residents.known import _turns_kernel

    rng = np.random.default_rng(0)
    logp = np.log(np.full((3, 3), 1 / 3))
    _viterbi_kernel(np.log(rng.uniform(0.1, 1.0, (6, 3))), rng.random(6) < 0.5, logp, logp, logp[0].copy())
    _turns_kernel(rng.dirichlet(np.ones(2), size=5), np.cumsum(rng.random(5)), 120.0)


def readers() -> None:
    from onebit.readers.beams import decode_passes
    from onebit.readers.motion import DebounceRules, debounce

    ev = pl.DataFrame(
        {
            "line": [2, 3, 4, 5],
            "t": [0.0, 0.1, 0.2, 0.3],
            "beam": "a",
            "pair": ["a", "b", "a", "b"],
            "blocked": [True, True, False, False],
        }
    )
    decode_passes(ev, compiled=True)
    from onebit.readers import kernels

    # what a reader calls once numba is loaded: a toggle log's repeats, the separators of messy lines
    kernels.toggle_repeats(np.array([0, 1, 0], dtype=np.int64), np.array([True, True, False]), 2)
    kernels.separators_per_line(np.frombuffer(b"a,b\nc\n", dtype=np.uint8), ord(","))
    edges = pl.DataFrame({"line": [2, 3], "t": [0.0, 1.0], "sensor": "s", "on": [True, False]})
    debounce(edges, ["s"], DebounceRules(chatter_window=0.1, min_on=0.1), compiled=True)


def main() -> None:
    t_all = time.perf_counter()
    for warm in (findinghumo, intruder, beams, clustertrack, binpf, binpf_runs, homes, simulators, readers, scoring):
        t0 = time.perf_counter()
        warm()
        print(f"kernels: {warm.__name__:<13} {time.perf_counter() - t0:6.2f} s", flush=True)
    print(f"all kernels compiled or loaded from numba's cache in {time.perf_counter() - t_all:.1f} s")


if __name__ == "__main__":
    main()
