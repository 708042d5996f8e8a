"""Issue #16, "speed at the floor": every row of the issue's table measured in one process,
ours beside its peer or floor on the same input, the ratio ``ours / peer`` and the growth
exponent of ours over the sizes (10^4 to 10^6 events where the row has events), written to
``benchmarks/results.csv`` (:mod:`benchmarks.results`).

Rows (the goal of each is printed beside it):

* beams.csv and motion.csv readers vs ``pl.read_csv`` (the floor), and the same logs with 5 bad
  lines (only those typed row by row) vs the clean log's ``pl.read_csv``;
* first-order Viterbi vs hmmlearn's C++ (``_hmmc.viterbi``), and the first-call cost of the
  compiled kernels (cold numba cache, warm cache);
* the trackers' call shape (7-slot windows) and the findinghumo stage vs its numpy reference;
* the SIR particle-filter step vs Stone Soup (``pip install -e .[bench]``);
* intruder on long motion logs (time and peak memory, fresh process);
* istate on proximity-line vs its every-pair reference;
* clustertrack, two people on a 9 x 4 proximity grid for 4 minutes, vs the line scenario;
* ``region_scores`` vs its row-by-row reference; camera reader peak memory vs video length;
* start-up (``import onebit``) vs ``import numpy, polars``; Algorithm 1 with variations A-E vs
  the base; ``make demo`` (set ``ONEBIT_BENCH_DEMO=0`` to skip it).

``ONEBIT_BENCH_QUICK=1`` runs every row on small sizes (a smoke test of the benchmark).
Tests never assert on time; this module does not either (it only prints and records).

Run with ``python -m benchmarks.bench_table`` (``--rows readers,startup`` for some rows only).
"""

from __future__ import annotations

import argparse
import functools
import os
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import polars as pl

from benchmarks.results import HEADER, Result, Table, best, growth, peak_mb

QUICK = os.environ.get("ONEBIT_BENCH_QUICK", "") not in ("", "0")
ROOT = Path(__file__).resolve().parent.parent
PY = sys.executable


def _sizes(full, quick):
    return quick if QUICK else full


@contextmanager
def patched(obj, name, value):
    old = getattr(obj, name)
    setattr(obj, name, value)
    try:
        yield
    finally:
        setattr(obj, name, old)


# --------------------------------------------------------------------------- inputs


def toggle_log(n_rows: int, sensors, *, seed: int = 0, rate: float = 5.0, chatter: float = 0.1) -> pl.DataFrame:
    """A raw PIR toggle log of about ``n_rows`` rows (t, sensor, value), ``rate`` rows/s over
    all sensors: per sensor alternating on/off periods, 1 in 10 rising edges followed by a
    relay flicker (off then on again within ``chatter`` s) for the debounce to undo."""
    rng = np.random.default_rng(seed)
    n = len(sensors)
    periods = max(1, n_rows // (2 * n) // 1)
    dur = n_rows / rate
    rows = []
    for _i, s in enumerate(sensors):  # one vectorised draw per sensor
        gap = rng.exponential(dur / periods / 2, periods)
        on_t = np.cumsum(gap + rng.uniform(0.3, 2.0, periods))
        off_t = on_t + rng.uniform(0.2, 1.5, periods)
        ok = off_t < np.r_[on_t[1:], np.inf] - 0.2
        on_t, off_t = on_t[ok], off_t[ok]
        fl = rng.random(on_t.size) < 0.1
        f_off = on_t[fl] + chatter * 0.3
        f_on = f_off + chatter * 0.2
        t = np.concatenate([on_t, off_t, f_off, f_on])
        v = np.concatenate([np.ones(on_t.size), np.zeros(off_t.size), np.zeros(f_off.size), np.ones(f_on.size)]).astype(
            np.int8
        )
        rows.append(pl.DataFrame({"t": t.round(3), "sensor": s, "value": v}))
    return pl.concat(rows).sort("t", maintain_order=True)


def grid_people(people: int = 2, instants: int = 240, nx: int = 9, ny: int = 4, seed: int = 0, speed: float = 0.5):
    """Proximity sensors every R on an ``nx x ny`` grid, ``people`` random walkers (reflected
    at the walls) for ``instants`` 1-s instants (a ProximityWorld)."""
    from onebit.datasets.proximity_sim import ProximityWorld, detect

    rng = np.random.default_rng(seed)
    gx, gy = np.meshgrid(np.arange(nx) + 0.5, np.arange(ny) + 0.5)
    xy = np.c_[gx.ravel(), gy.ravel()]
    n = len(xy)
    pos = rng.uniform([0.2, 0.2], [nx - 0.2, ny - 0.2], size=(people, 2))
    head = rng.uniform(0, 2 * np.pi, people)
    tr = np.zeros((people, instants, 2))
    for t in range(instants):  # input generation, not timed
        tr[:, t] = pos
        head += rng.normal(0, 0.4, people)
        pos = pos + speed * np.c_[np.cos(head), np.sin(head)]
        hit_x = (pos[:, 0] < 0.1) | (pos[:, 0] > nx - 0.1)
        hit_y = (pos[:, 1] < 0.1) | (pos[:, 1] > ny - 0.1)
        pos = np.clip(pos, 0.1, [nx - 0.1, ny - 0.1])
        head = np.where(hit_x, np.pi - head, head)
        head = np.where(hit_y, -head, head)
    d = np.linalg.norm(tr.transpose(1, 0, 2)[:, None, :, :] - xy[None, :, None, :], axis=-1)
    on = detect(d, np.ones(n), np.ones(n), 0.5, rng)
    return ProximityWorld("grid-people", "m", (0.0, 0.0, float(nx), float(ny)), xy, np.ones(n), np.ones(n), tr, on)


# --------------------------------------------------------------------------- rows


def with_bad_lines(path: Path, k: int = 5) -> None:
    """Spoil ``k`` evenly spaced data lines of a CSV log in place: an unknown name, an extra
    field, a byte that is not UTF-8, a stray quote, a ``nan`` stamp (in turn)."""
    lines = path.read_bytes().split(b"\n")
    for j in range(k):
        i = 1 + (j + 1) * (len(lines) - 2) // (k + 1)
        f = lines[i].split(b",")
        kind = j % 5
        if kind == 0:
            f[1] = b"zz"
        elif kind == 1:
            f.append(b"x")
        elif kind == 2:
            f[1] += b"\xff"
        elif kind == 3:
            f[1] = b'"' + f[1] + b'"x'
        else:
            f[0] = b"nan"
        lines[i] = b",".join(f)
    path.write_bytes(b"\n".join(lines))


def readers(t: Table) -> None:
    from benchmarks.bench_reader import generate_beam_log
    from onebit.datasets.builtin import builtin_site
    from onebit.readers.beams import decode_beam_log
    from onebit.readers.motion import DebounceRules, read_motion_csv

    site = builtin_site("building")
    beams = site.beam_ids
    sensors = [f"pir{i}" for i in range(1, 15)]
    rules = DebounceRules(chatter_window=0.1, min_on=0.1)
    sizes = _sizes((10_000, 100_000, 1_000_000), (10_000, 30_000))
    with tempfile.TemporaryDirectory() as tmp:
        for what, make, read, bad in (
            ("beams.csv reader", lambda n: generate_beam_log(n, beams)[0], lambda p: decode_beam_log(p, beams), 0),
            (
                "motion.csv reader (debounce)",
                lambda n: toggle_log(n, sensors),
                lambda p: read_motion_csv(p, sensors, rules=rules),
                0,
            ),
            # the same logs with 5 bad lines: only those are typed row by row (floor: the clean file's read)
            (
                "beams.csv reader, 5 bad lines",
                lambda n: generate_beam_log(n, beams)[0],
                lambda p: decode_beam_log(p, beams),
                5,
            ),
            (
                "motion.csv reader, 5 bad lines",
                lambda n: toggle_log(n, sensors),
                lambda p: read_motion_csv(p, sensors, rules=rules),
                5,
            ),
        ):
            ours, peers = [], []
            for n in sizes:
                clean = Path(tmp) / f"log_{n}.csv"
                make(n).write_csv(clean)
                path = clean
                if bad:
                    path = Path(tmp) / f"bad_{n}.csv"
                    path.write_bytes(clean.read_bytes())
                    with_bad_lines(path, bad)
                read(path)  # warm: numba start, file cache
                pl.read_csv(clean)
                # ours and the floor in turn, best of each: both see the same load on a shared machine
                to, tp, out = float("inf"), float("inf"), None
                for _ in range(5 if n >= 10**6 else 7):
                    t0 = time.perf_counter()
                    out = read(path)
                    t1 = time.perf_counter()
                    pl.read_csv(clean)
                    to, tp = min(to, t1 - t0), min(tp, time.perf_counter() - t1)
                assert out.rejects.height >= bad if bad else out.rejects.height == 0
                ours.append(to)
                peers.append(tp)
            g = growth(sizes, ours)
            for n, to, tp in zip(sizes, ours, peers):
                t.add(
                    Result(
                        what,
                        f"{what} {n:.0e} rows",
                        n,
                        "s",
                        to,
                        tp,
                        "pl.read_csv" + (" of the clean log" if bad else ""),
                        g,
                        "<= 1.5x pl.read_csv, linear",
                        to / tp <= 1.5,
                    )
                )


def viterbi(t: Table) -> None:
    from hmmlearn import _hmmc

    from onebit.models.graph_hmm import kernels
    from onebit.models.graph_hmm import viterbi as ref

    rng = np.random.default_rng(0)
    D = 10_000
    for s in _sizes((20, 100, 400), (20, 100)):
        pi = np.log(rng.dirichlet(np.ones(s)))
        a = np.log(rng.dirichlet(np.ones(s), size=s))
        b = np.log(rng.random((D, s)) + 1e-3)
        kernels.viterbi_first_order(pi, a, b[:3])
        to, (p, lp) = best(lambda: kernels.viterbi_first_order(pi, a, b), 5, clock=time.process_time)
        pi_p, a_p = np.exp(pi), np.exp(a)
        tp, (lp_h, p_h) = best(lambda: _hmmc.viterbi(pi_p, a_p, b), 5, clock=time.process_time)
        assert np.array_equal(p, p_h), "paths differ from hmmlearn"
        t.add(
            Result(
                "first-order Viterbi",
                f"viterbi 1e4 steps, {s} states",
                s,
                "s cpu",
                to,
                tp,
                "hmmlearn _hmmc.viterbi (C++)",
                None,
                "<= 1.0x hmmlearn",
                to <= tp,
            )
        )
    steps = _sizes((10_000, 100_000, 1_000_000), (10_000, 100_000))
    pi = np.log(rng.dirichlet(np.ones(20)))
    a = np.log(rng.dirichlet(np.ones(20), size=20))
    times = []
    for d in steps:
        b = np.log(rng.random((d, 20)) + 1e-3)
        times.append(best(lambda: kernels.viterbi_first_order(pi, a, b), 3, clock=time.process_time)[0])
    g = growth(steps, times)
    for d, to in zip(steps, times):
        t.add(
            Result(
                "first-order Viterbi",
                "viterbi 20 states, steps",
                d,
                "s cpu",
                to,
                None,
                "",
                g,
                "linear in steps",
                g is not None and g < 1.2,
            )
        )
    # the call shape of the trackers: 10^4 windows of 7 slots (reference = the numpy decoders)
    s, L, calls = 16, 7, _sizes(10_000, 2_000)
    logs = [np.log(rng.random((L, s)) + 1e-3) for _ in range(64)]
    pi = np.log(rng.dirichlet(np.ones(s)))
    a1 = np.log(rng.dirichlet(np.ones(s), size=s))
    a2 = np.log(rng.dirichlet(np.ones(s), size=(s, s)))
    stay = np.diag(a1).copy()
    for name, fk, fr in (
        ("1st order", lambda b: kernels.viterbi_first_order(pi, a1, b), lambda b: ref.viterbi_first_order(pi, a1, b)),
        (
            "2nd order",
            lambda b: kernels.viterbi_motion_second_order(pi, stay, a2, b),
            lambda b: ref.viterbi_motion_second_order(pi, stay, a2, b),
        ),
    ):
        fk(logs[0])
        tk, _ = best(lambda: [fk(logs[i % 64]) for i in range(calls)], 3, clock=time.process_time)
        tr, _ = best(lambda: [fr(logs[i % 64]) for i in range(calls)], 2, clock=time.process_time)
        t.add(
            Result(
                "Viterbi call shape",
                f"7-slot window, {s} states, {name}",
                calls,
                "us/call",
                tk / calls * 1e6,
                tr / calls * 1e6,
                "numpy reference",
                None,
                "kernel 1-2 / 8-47 us per call",
                None,
            )
        )


def compile_times(t: Table) -> None:
    """First call of each kernel module in a fresh process: cold numba cache (compilation)
    and warm cache (what a second ``onebit run`` pays)."""
    calls = {
        "findinghumo": "import numpy as np\nfrom onebit.models.graph_hmm.adaptive import DecoderParams, decode_run\n"
        "from onebit.models.graph_hmm.eatg import hop_matrix, layout_eatg\n"
        "n=('a','b','c');e=layout_eatg(n,hop_matrix(n,(('a','b'),('b','c'))))\n"
        "T=__import__('time').perf_counter()\n"
        "decode_run(np.eye(3,dtype=bool)[[0,1,2,1]],e,params=DecoderParams(mode='full2'));decode_run(np.eye(3,dtype=bool)[[0,1]],e,params=DecoderParams(mode='full1'))",
        "intruder": "import numpy as np, shapely\nfrom onebit.models.motion import Motion, Room\nfrom onebit.models.pir import Deployment, WorldGrid\n"
        "from onebit.trackers.intruder.filter import run_filter\n"
        "d=Deployment(('s',),WorldGrid(0,0,1,4,4),np.ones((1,4,4)),np.zeros(1),np.zeros(1),np.zeros(1),np.array([16]),())\n"
        "T=__import__('time').perf_counter()\n"
        "run_filter(np.ones((2,1),bool),np.zeros((2,1),bool),d,Room(shapely.box(0,0,4,4)),Motion(2,4,1.5,4,50),n_particles=10,half_w=1,half_d=1,rng=np.random.default_rng(0),compiled=True)",
        "beams": "import numpy as np\nfrom onebit.trackers.beams.assignment import Constraints, assign_agents\n"
        "T=__import__('time').perf_counter()\n"
        "assign_agents(np.array([0,1]),np.array([1,0]),2,compiled=True);assign_agents(np.array([0,1]),np.array([1,0]),2,constraints=Constraints(max_track_length=5),compiled=True)",
        "clustertrack": "import numpy as np\nfrom onebit.trackers.clustertrack.kernels import scan_sorted\n"
        "T=__import__('time').perf_counter()\n"
        "scan_sorted(np.zeros(3,np.int64),np.zeros((3,1)),np.zeros((1,1)),1.0,2,3,1.0)",
        "readers": "import numpy as np\nfrom onebit.readers.kernels import beam_passes, debounce_masks\n"
        "T=__import__('time').perf_counter()\n"
        "beam_passes(np.zeros(2,np.int64),np.zeros(2,np.int8),np.ones(2,bool),1);debounce_masks(np.zeros(2,np.int64),np.zeros(2,bool),np.zeros(2),np.zeros(1),np.zeros(1),1,1e-9)",
    }
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        for name, code in calls.items():
            code += "\nprint('FIRST_CALL', __import__('time').perf_counter()-T)"
            got = []
            for _ in range(2):  # cold, then warm
                out = subprocess.run([PY, "-c", code], capture_output=True, text=True, env=env, cwd=ROOT)
                got.append(float(out.stdout.split("FIRST_CALL")[-1]) if "FIRST_CALL" in out.stdout else float("nan"))
            t.add(
                Result(
                    "first-call compile time",
                    f"kernels: {name} (cold / warm cache)",
                    1,
                    "s",
                    got[0],
                    got[1],
                    "warm cache (second process)",
                    None,
                    "compile once per install (cache=True); warm start < 1 s",
                    got[1] < 1.0,
                )
            )


def findinghumo_stage(t: Table) -> None:
    from onebit.core.site import load_site
    from onebit.datasets.hallway_sim import write_hallway_dataset
    from onebit.models.graph_hmm import decoding, joint
    from onebit.models.graph_hmm.adaptive import DecoderParams
    from onebit.readers.motion import read_motion_csv
    from onebit.trackers.findinghumo import stage as S

    durations = _sizes((150.0, 600.0, 1500.0), (150.0, 300.0))
    ours = []
    with tempfile.TemporaryDirectory() as tmp:
        for dur in durations:
            ds = write_hallway_dataset(Path(tmp) / f"h{dur:.0f}", seed=7, duration=dur, users=3, drop=0.02)
            site = load_site(ds / "site.toml")
            mo = read_motion_csv(ds / "motion.csv", list(site.sensor_graph.nodes)).motion
            cfg = S.FindingHumoConfig()
            run = lambda: S.run_findinghumo({"motion": mo}, site, cfg)  # noqa: E731
            run()
            to, out = best(run, 3, clock=time.process_time)
            with (
                patched(decoding, "DecoderParams", functools.partial(DecoderParams, compiled=False)),
                patched(joint, "_pair_viterbi", joint.pair_viterbi_reference),
            ):
                tr, ref = best(run, 2, clock=time.process_time)
            assert out["tracks"].equals(ref["tracks"]), "compiled and reference decoders differ"
            ours.append(to)
            t.add(
                Result(
                    "findinghumo stage",
                    f"findinghumo stage, hallway {dur:.0f} s",
                    dur,
                    "s cpu",
                    to,
                    tr,
                    "numpy decoders (compiled=False)",
                    None,
                    ">= 5x faster",
                    tr / to >= 5,
                )
            )
    g = growth(durations, ours)
    t.results[-1].growth = g


def particle_filter(t: Table) -> None:
    """Ours per step without the prior (``ours_step``, best of 3), as the Stone Soup peer is timed."""
    from benchmarks.bench_intruder import ours, ours_step, scenario

    try:
        import stonesoup  # noqa: F401

        from benchmarks.bench_intruder import stonesoup_filter
    except ImportError:
        stonesoup_filter = None
    site, dep, fired, blind, _, _ = scenario("pir14", 4.0, duration=60.0)
    ours(site, dep, fired[:2], blind[:2], 100)
    sizes = _sizes((1_000, 10_000, 100_000, 1_000_000), (1_000, 10_000))
    res = []
    for n in sizes:
        k = 20 if n <= 10_000 else (6 if n <= 100_000 else 3)
        to = min(ours_step(site, dep, fired[:k], blind[:k], n)[0] for _ in range(3))  # best of 3, as ``best``
        tp = stonesoup_filter(site, dep, fired[:k], blind[:k], n)[0] if stonesoup_filter else None
        res.append((n, to, tp))
    g = growth([r[0] for r in res], [r[1] for r in res])
    for n, to, tp in res:
        t.add(
            Result(
                "SIR particle-filter step",
                f"SIR step, {n:.0e} particles (ns/particle)",
                n,
                "ns/particle cpu",
                to / n * 1e9,
                tp / n * 1e9 if tp else None,
                "Stone Soup ParticlePredictor/Updater",
                g,
                ">= 10x Stone Soup, flat ns/particle",
                (tp / to >= 10) if tp else None,
            )
        )


def intruder_long(t: Table) -> None:
    from onebit.datasets.pir_sim import simulate, site_toml

    d, _ = simulate("pir14", seed=7, duration=60.0, refractory=4.0)
    sizes = _sizes((10_000, 100_000, 1_000_000), (10_000, 30_000))
    res = []
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "site.toml").write_text(site_toml(d))
        ids = [m["id"] for m in d["motion_sensors"]]
        for n in sizes:
            path = Path(tmp) / f"motion_{n}.csv"
            toggle_log(n, ids, seed=n).write_csv(path)
            setup = (
                "import time\nfrom pathlib import Path\nfrom onebit.core.site import load_site\n"
                "from onebit.readers.motion import read_motion_csv, MotionConfig, site_rules\n"
                "from onebit.trackers.intruder.stage import IntruderConfig, run\n"
                f"site = load_site(Path({tmp!r}) / 'site.toml')\n"
                f"mo = read_motion_csv({str(path)!r}, [m.id for m in site.motion_sensors], rules=site_rules(site, MotionConfig())).motion\n"
                "t0 = time.perf_counter()"
            )
            call = "c0 = time.process_time()\nout = run({'motion': mo}, site, IntruderConfig())\nprint('STAGE_S', time.process_time() - c0)"
            out = subprocess.run([PY, "-c", setup + "\n" + call], capture_output=True, text=True, cwd=ROOT)
            secs = float(out.stdout.split("STAGE_S")[-1]) if "STAGE_S" in out.stdout else float("nan")
            mb = peak_mb(setup, call)
            res.append((n, secs, mb))
    g = growth([r[0] for r in res], [r[1] for r in res])
    gm = growth([r[0] for r in res], [max(r[2] or 1.0, 1.0) for r in res])
    for n, secs, mb in res:
        t.add(
            Result(
                "intruder on a long motion log",
                f"intruder stage, {n:.0e}-row log",
                n,
                "s cpu",
                secs,
                None,
                "",
                g,
                "< 60 s at 1e6 rows",
                secs < 60 if n >= 10**6 else None,
            )
        )
        t.add(
            Result(
                "intruder on a long motion log",
                f"intruder stage peak MB, {n:.0e}-row log",
                n,
                "MB",
                mb or float("nan"),
                None,
                "",
                gm,
                "< 1 GB at 1e6 rows",
                (mb or 0) < 1000 if n >= 10**6 else None,
            )
        )


def _every_pair_memo():
    """A pair memo class that remembers nothing: every region pair is computed (the reference)."""
    from onebit.trackers.istate.core import PairMemo

    class EveryPair(PairMemo):
        remember_steps = False  # every observation step computed too

        def pairs(self, left, right, kl, kr, table, op, dtype):
            self.computed += len(left)
            return np.asarray(op(left, right), dtype=dtype) if len(left) else np.zeros(0, dtype=dtype)

        def geometries(self, left, right, name, op):  # every region projected, intersected, united (no ids made)
            return np.asarray(op(left, right), dtype=object)

    return EveryPair


def istate(t: Table) -> None:
    from onebit.core.site import load_site
    from onebit.datasets.proximity_sim import SCENARIO_SPECS
    from onebit.readers.motion import read_motion_csv
    from onebit.trackers.istate import core
    from onebit.trackers.istate import stage as S

    instants = _sizes((20, 80, 320), (20, 40))
    ours = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in instants:
            ds = Path(tmp) / f"pl{n}"
            SCENARIO_SPECS["proximity-line"].write(ds, seed=7, params={"instants": str(n)})
            site = load_site(ds / "site.toml")
            prox = read_motion_csv(ds / "proximity.csv", [p.id for p in site.proximity_sensors]).motion
            run = lambda: S.run({"proximity": prox}, site, S.IStateConfig())  # noqa: E731
            to, out = best(run, 2, clock=time.process_time)
            tr = None
            if n <= 80 or not QUICK:
                every = _every_pair_memo()  # the stage's run-wide memo and any a function makes
                with (
                    patched(core, "cap_elements", core.cap_elements_reference),
                    patched(core, "PairMemo", every),
                    patched(S, "PairMemo", every),
                ):
                    tr, ref = best(run, 1, clock=time.process_time)
                assert out["regions"].equals(ref["regions"]), "istate differs from its every-pair reference"
            ours.append(to)
            t.add(
                Result(
                    "istate",
                    f"istate proximity-line {n} instants",
                    n,
                    "s cpu",
                    to,
                    tr,
                    "every region pair, full cap matrix",
                    None,
                    ">= 10x faster, linear in instants",
                    (tr / to >= 10) if tr else None,
                )
            )
    g = growth(instants, ours)
    for r in t.results[-len(instants) :]:
        r.growth = g


def clustertrack(t: Table) -> None:
    from shapely.geometry import box

    from onebit.datasets.proximity_sim import make_world
    from onebit.trackers.clustertrack.algorithm import clustertrack as run_ct
    from onebit.trackers.clustertrack.algorithm import consensus
    from onebit.trackers.clustertrack.feasible import SensorArray
    from onebit.trackers.clustertrack.space import FeasibleSpace
    from onebit.trackers.clustertrack.stage import ClusterTrackConfig, params_for

    def stage_like(w, cfg):
        """What the stage computes: feasible spaces, the run with Appendix B, the consensus."""
        sa = SensorArray(tuple(f"p{i}" for i in range(len(w.sensor_xy))), w.sensor_xy, w.r_inner, w.r_outer)
        dim = 1 if sa.is_1d else 2
        sp = FeasibleSpace.build(
            w.on,
            np.arange(w.on.shape[0], dtype=float),
            sa,
            box(*w.boundary),
            dim=dim,
            cell=sa.radius / cfg.raster_per_r,
        )
        p = params_for(sp, sa.radius, cfg)
        res = run_ct(
            sp, p, np.random.default_rng(cfg.seed), max_reruns=cfg.reruns, record=True, high_cost=cfg.rerun_cost_ratio
        )
        consensus(
            sp,
            p,
            list(range(cfg.seed, cfg.seed + cfg.consensus_runs)),
            ratio=cfg.consensus_ratio,
            min_support=cfg.consensus_support,
            max_reruns=cfg.reruns,
            high_cost=cfg.rerun_cost_ratio,
            known={cfg.seed: res},
        )
        return res

    cfg = ClusterTrackConfig()
    line = make_world("proximity-line", seed=7)
    stage_like(line, cfg)
    tl, _ = best(lambda: stage_like(line, cfg), 2, clock=time.process_time)
    minutes = _sizes((4,), (1,))[0]
    for people in (1, 2):
        w = grid_people(people, instants=60 * minutes)
        to, res = best(lambda: stage_like(w, cfg), 1, clock=time.process_time)
        t.add(
            Result(
                "clustertrack 2-D",
                f"clustertrack 9x4 grid, {people} people, {minutes} min",
                people,
                "s cpu",
                to,
                tl,
                "proximity-line (the simulator's line scenario)",
                None,
                "< 10 s",
                to < 10,
            )
        )


def region_scores(t: Table) -> None:
    """Scores of long simulated beams runs (beams-lab, 2 agents, truth at 10 Hz): the crossings
    decoded, assigned by the beams stage and matched to the truth as the pipeline does (not
    timed), then ``region_scores`` (timed) beside its row-by-row reference."""
    from onebit._testing.oracles import region_scores_reference
    from onebit.core.region_graph import build_region_graph
    from onebit.core.site import load_site
    from onebit.datasets.beams_sim import write_beams_dataset
    from onebit.readers.beams import decode_beam_log
    from onebit.scoring.crossings import assignment_scores, match_crossings, true_crossings_from_truth
    from onebit.scoring.crossings import region_scores as ours_fn
    from onebit.trackers.beams import BeamsConfig
    from onebit.trackers.beams import run as run_beams

    sizes = _sizes((10_000, 100_000, 576_000), (10_000, 40_000))
    res = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes:
            ds = write_beams_dataset(Path(tmp) / f"b{n}", "beams-lab", seed=7, duration=n / 20.0, camera=False)
            site = load_site(ds / "site.toml")
            rg = build_region_graph(site)
            truth = pl.read_csv(ds / "truth.csv")
            crossings = decode_beam_log(ds / "beams.csv", site.beam_ids).crossings
            out = run_beams({"crossings": crossings, "region_graph": rg}, site, BeamsConfig())
            matches = match_crossings(crossings, true_crossings_from_truth(truth, site, rg), 1.0)
            _, mapping = assignment_scores(matches, out["assignment"])
            tracks = out["tracks"]
            to, a = best(lambda: ours_fn(tracks, truth, mapping, rg, tracker="beams"), 3)
            tr, b = best(lambda: region_scores_reference(tracks, truth, mapping, rg, tracker="beams"), 2)
            assert a.equals(b), "region_scores differs from its reference"
            res.append((truth.height, to, tr))
    g = growth([r[0] for r in res], [r[1] for r in res])
    for n, to, tr in res:
        t.add(
            Result(
                "region_scores",
                f"region_scores {n} truth rows",
                n,
                "s",
                to,
                tr,
                "row-by-row reference",
                g,
                "<= the issue's vectorised version (1.9 s vs 6.0 s: <= 0.32x the reference)",
                to / tr <= 0.32,
            )
        )


def camera(t: Table) -> None:
    from benchmarks.bench_camera import RADIUS, lab_truth
    from onebit.datasets.builtin import builtin_site
    from onebit.datasets.camera_render import render_overhead_video

    site = builtin_site("lab")
    frames = _sizes((300, 1000, 3000), (100, 300))
    res = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in frames:
            path = Path(tmp) / f"lab_{n}.mp4"
            render_overhead_video(path, site, lab_truth(site, n), seed=0, radius=RADIUS)
            # the libraries the reader imports on first use (cv2, scipy) are loaded in the setup: their
            # code is not memory the reading holds
            setup = (
                "from pathlib import Path\nimport cv2, scipy.optimize, scipy.spatial.distance\nfrom onebit.datasets.builtin import builtin_site\n"
                "from onebit.readers.camera import read_camera\nsite = builtin_site('lab')"
            )
            mb = peak_mb(setup, f"read_camera(Path({str(path)!r}), site)")
            video_mb = n * site.camera.width * site.camera.height / 2**20
            res.append((n, mb or float("nan"), video_mb))
    g = growth([r[0] for r in res], [max(r[1], 1.0) for r in res])
    for n, mb, video in res:
        t.add(
            Result(
                "camera reader memory",
                f"camera reader peak MB, {n} frames",
                n,
                "MB",
                mb,
                video,
                "the decoded video (K H W bytes)",
                g,
                "independent of video length (growth ~0)",
                g is not None and g < 0.3,
            )
        )


def startup(t: Table) -> None:
    def wall(code, n=5):
        ts = []
        for _ in range(n):
            t0 = time.perf_counter()
            subprocess.run([PY, "-c", code], check=True, cwd=ROOT)
            ts.append(time.perf_counter() - t0)
        return min(ts)

    floor = wall("import numpy, polars")
    for what, code in (
        ("import onebit", "import onebit"),
        ("import onebit; onebit.load_site", "import onebit; onebit.load_site"),
        ("import onebit.cli (the CLI)", "import onebit.cli"),
    ):
        tw = wall(code)
        t.add(
            Result(
                "start-up", f"start-up: {what}", 1, "s wall", tw, floor, "import numpy, polars", None, "< 1 s", tw < 1.0
            )
        )


def algorithm1(t: Table) -> None:
    from benchmarks.bench_assignment import all_variations, random_crossings
    from onebit.core.region_graph import build_region_graph
    from onebit.datasets.builtin import builtin_site
    from onebit.trackers.beams.assignment import assign_agents

    rg = build_region_graph(builtin_site("building"))
    p = len(rg.names)
    sizes = _sizes((10_000, 100_000, 1_000_000), (10_000, 100_000))
    res = []
    for m in sizes:
        beams, dirs, _, _ = random_crossings(rg, m)
        src, tgt = rg.endpoint_arrays(beams, dirs)
        times = np.arange(m, dtype=np.float64)
        tb, base = best(lambda: assign_agents(src, tgt, p, compiled=True), 3)
        cons = all_variations(src, tgt, p, base.initial_region)
        ta, _ = best(lambda: assign_agents(src, tgt, p, constraints=cons, times=times, compiled=True), 3)
        res.append((m, ta, tb))
    g = growth([r[0] for r in res], [r[1] for r in res])
    for m, ta, tb in res:
        t.add(
            Result(
                "Algorithm 1 variations",
                f"Algorithm 1 A-E, {m:.0e} crossings",
                m,
                "s",
                ta,
                tb,
                "base Algorithm 1 (compiled)",
                g,
                "<= 2x base",
                ta / tb <= 2,
            )
        )


def demo(t: Table) -> None:
    if os.environ.get("ONEBIT_BENCH_DEMO", "1") == "0" or QUICK:
        print("(make demo: skipped, ONEBIT_BENCH_DEMO=0 or quick run)")
        return
    onebit = str(Path(PY).with_name("onebit"))
    with tempfile.TemporaryDirectory() as b:
        steps = [
            ["simulate", "beams-lab", f"{b}/beams-lab", "--seed", "7", "--duration", "180", "--agents", "2"],
            ["run", f"{b}/beams-lab", "--out", f"{b}/run"],
            ["report", f"{b}/run"],
            ["simulate", "pir14", f"{b}/pir14", "--seed", "7", "--param", "refractory=4"],
            ["run", f"{b}/pir14", "--out", f"{b}/pir14-run"],
            ["simulate", "proximity-line", f"{b}/proximity-line", "--seed", "7"],
            ["run", f"{b}/proximity-line", "--out", f"{b}/proximity-line-run"],
            ["simulate", "hallway", f"{b}/hallway", "--seed", "7", "--users", "3", "--duration", "150"],
            ["run", f"{b}/hallway", "--out", f"{b}/hallway-run"],
            ["simulate", "istate-room", f"{b}/istate-room", "--seed", "7"],
            ["run", f"{b}/istate-room", "--out", f"{b}/istate-room-run"],
        ]
        t0 = time.perf_counter()
        render = 0.0
        for s in steps:
            t1 = time.perf_counter()
            subprocess.run([onebit, *s], check=True, capture_output=True, cwd=ROOT)
            if s[:2] == ["simulate", "beams-lab"]:
                render = time.perf_counter() - t1
        total = time.perf_counter() - t0
    t.add(
        Result(
            "make demo",
            "make demo (warm)",
            1,
            "s wall",
            total,
            render,
            "simulate beams-lab (renders camera.mp4)",
            None,
            "< 45 s",
            total < 45,
        )
    )


ROWS = (
    readers,
    viterbi,
    compile_times,
    findinghumo_stage,
    particle_filter,
    intruder_long,
    istate,
    clustertrack,
    region_scores,
    camera,
    startup,
    algorithm1,
    demo,
)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_table", description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--rows", default="", help="comma-separated rows to run (default: all): " + ", ".join(r.__name__ for r in ROWS)
    )
    args = parser.parse_args(argv)
    wanted = [w.strip() for w in args.rows.split(",") if w.strip()]
    unknown = sorted(set(wanted) - {r.__name__ for r in ROWS})
    if unknown:
        parser.error(f"unknown rows {unknown}; the rows are {[r.__name__ for r in ROWS]}")
    table = Table()
    print(HEADER)
    failed = []
    for row in ROWS:
        if wanted and row.__name__ not in wanted:
            continue
        t0 = time.perf_counter()
        try:
            row(table)
        except Exception as exc:  # report the row and go on; the run still writes what it measured
            import traceback

            traceback.print_exc()
            failed.append(f"{row.__name__}: {exc}")
        print(f"  ({row.__name__}: {time.perf_counter() - t0:.0f} s)", flush=True)
    print(
        "\nratio = ours / peer (below 1: ours is faster or smaller); growth = log-log slope of ours over the row's sizes "
        "(1 = linear, 0 = flat)"
    )
    if QUICK:
        print("(quick run: benchmarks/results.csv not written)")
    else:
        path = table.write()
        print(f"wrote {path.relative_to(ROOT)} ({len(table.results)} rows)")
    if failed:
        raise RuntimeError("rows failed: " + "; ".join(failed))


if __name__ == "__main__":
    main()
