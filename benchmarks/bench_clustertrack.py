"""CLUSTERTRACK: the vectorised Algorithm 1 scan against a direct per-particle transcription.

Both scan the same candidates (K_{t-1} = H Q particles of length t = 10, each extended by
m_t = m_o S_F samples, S_F = 2 R per target, random costs) and must keep the same particles.
Prints time and peak memory (tracemalloc) per instant for both and the ratio, against H,
m_o R and the number of targets Q, then the whole tracker per instant on proximity-line.
"""

from __future__ import annotations

import time
import tracemalloc

import numpy as np

from onebit._testing.oracles import scan_clusters_direct
from onebit.trackers.clustertrack.algorithm import _norm, scan_clusters


def instant(H: int, m_o_r: float, Q: int, t: int = 10, seed: int = 0):
    rng = np.random.default_rng(seed)
    kprev = H * Q
    s_f = 2.0 * Q
    m = max(1, int(round(m_o_r * s_f)))
    centres = rng.uniform(0, 6 * Q, size=Q)
    prev = centres[rng.integers(0, Q, kprev)][:, None, None] + rng.normal(0, 0.3, size=(kprev, t - 1, 1))
    pd = np.sum(_norm(prev[:, None] - prev[None, :])[..., None], axis=(2, 3))
    parent = np.repeat(np.arange(kprev), m)
    x = prev[parent, -1] + rng.normal(0, 0.5, size=(kprev * m, 1))
    cost = rng.random(kprev * m)
    L = int(round(H * m_o_r * s_f))
    return dict(cost=cost, parent=parent, x=x, pd=pd, prev=prev, t=t, H=H, K=H * Q, L=L, D0=1.0)


def timed(fn):
    tracemalloc.start()
    t0 = time.perf_counter()
    out = fn()
    dt = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return out, dt, peak


def compare(H: int, m_o_r: float, Q: int) -> tuple[float, float]:
    c = instant(H, m_o_r, Q)
    # numba's start (and the compiled scan, from its cache) outside the timing
    scan_clusters(
        c["cost"],
        c["parent"],
        c["x"],
        c["pd"],
        c["t"],
        H=c["H"],
        K=c["K"],
        L=c["L"],
        D0=c["D0"],
        rng=np.random.default_rng(0),
    )
    ours, t_ours, m_ours = timed(
        lambda: scan_clusters(
            c["cost"],
            c["parent"],
            c["x"],
            c["pd"],
            c["t"],
            H=c["H"],
            K=c["K"],
            L=c["L"],
            D0=c["D0"],
            rng=np.random.default_rng(0),
        )
    )

    def direct():
        order = np.argsort(c["cost"])
        full = np.concatenate([c["prev"][c["parent"]], c["x"][:, None, :]], axis=1)
        return scan_clusters_direct(order, full, H=c["H"], K=c["K"], L=c["L"], D0=c["D0"])

    ref, t_ref, m_ref = timed(direct)
    assert np.array_equal(ours[0], ref[0]), "vectorised scan differs from the direct Algorithm 1"
    n = c["cost"].size
    print(
        f"  H={H:3d} m_oR={m_o_r:4.0f} Q={Q:2d}  candidates={n:7d}  L={c['L']:6d}  "
        f"ours {t_ours * 1e3:8.1f} ms {m_ours / 1e6:7.1f} MB   direct {t_ref * 1e3:9.1f} ms {m_ref / 1e6:7.1f} MB   "
        f"ratio {t_ref / t_ours:6.1f}x"
    )
    return t_ours, t_ref


def main() -> None:
    print("one instant of Algorithm 1 (scan + clustering), vectorised vs direct per-particle:")
    for H, m, Q in ((10, 15, 5), (25, 15, 5), (50, 15, 5), (25, 5, 5), (25, 30, 5), (25, 15, 2), (25, 15, 10)):
        compare(H, m, Q)
    print("whole tracker (feasible spaces + Algorithm 1 + Appendix B) per instant on proximity-line:")
    from scipy.optimize import linear_sum_assignment
    from shapely.geometry import box

    from onebit.datasets.proximity_sim import make_world
    from onebit.trackers.clustertrack.algorithm import clustertrack, rules_of_thumb, trajectory_distance
    from onebit.trackers.clustertrack.feasible import SensorArray
    from onebit.trackers.clustertrack.space import FeasibleSpace

    print("  (paper-literal rerun = high_cost 0: every Appendix B rerun with K = H q only)")
    for Q in (2, 5, 10):
        w = make_world("proximity-line", seed=0, targets=Q, params={"variant": "separated"})
        sa = SensorArray(tuple(map(str, range(len(w.sensor_xy)))), w.sensor_xy, w.r_inner, w.r_outer)
        for label, high_cost in (("ours", 10.0), ("paper-literal rerun", 0.0)):
            t0 = time.perf_counter()
            sp = FeasibleSpace.build(w.on, np.arange(20.0), sa, box(*w.boundary), dim=1, cell=0.1)
            p = rules_of_thumb(sp, H=25, m_o=15.0)
            r = clustertrack(sp, p, np.random.default_rng(0), high_cost=high_cost)
            dt = time.perf_counter() - t0
            D = trajectory_distance(w.truth[:, :, :1], r.tracks)
            a, b = linear_sum_assignment(D)
            found = int(np.sum(D[a, b] <= p.D0))
            print(
                f"  Q={Q:2d} {label:20s}: {dt / 20 * 1e3:7.1f} ms per instant ({r.reruns} reruns, {r.tracks.shape[0]} tracks,"
                f" {found}/{Q} targets found, {r.tracks.shape[0] - found} spurious)"
            )


if __name__ == "__main__":
    main()
