"""The number of users of the sensor-graph HMM trackers (hmm1, hmm2, findinghumo,
findinghumo-flow) is estimated inside the decoder: a one-resident log with lingering sensors
and a lost OFF is one user without ``targets``; ``targets`` bounds every decoding window."""

from __future__ import annotations

import dataclasses

import numpy as np
import polars as pl
import pytest

from onebit.core.site import site_from_dict
from onebit.core.tables import MOTION
from onebit.trackers.findinghumo.stage import FindingHumoConfig, HmmConfig, run_findinghumo, run_hmm1, run_hmm2
from onebit.trackers.findinghumo_flow.stage import FlowConfig, run_flow


def grid_home(n: int = 4, spacing: float = 1.5, targets: int | None = None):
    """``n`` x ``n`` ceiling motion sensors, 4-neighbour graph, no doors."""
    ids = {(i, j): f"M{i * n + j + 1:02d}" for i in range(n) for j in range(n)}
    edges = [
        [ids[i, j], ids[i + di, j + dj]] for (i, j) in ids for di, dj in ((0, 1), (1, 0)) if (i + di, j + dj) in ids
    ]
    data = {
        "name": "flat",
        "units": "m",
        "boundary": {"polygon": [[-1.0, -1.0], [n * spacing, -1.0], [n * spacing, n * spacing], [-1.0, n * spacing]]},
        "motion_sensors": [
            {"id": s, "position": [j * spacing, i * spacing], "range": spacing / 2} for (i, j), s in ids.items()
        ],
        "sensor_graph": {"edges": edges},
    }
    if targets is not None:
        data["targets"] = targets
    return site_from_dict(data, source="<flat>"), ids


def one_resident_log(seed: int, minutes: float = 15.0) -> tuple[pl.DataFrame, object]:
    """One person walking the grid (a step every 1-3 s, sitting 10-60 s a fifth of the time);
    each sensor stays on 2-8 s after the person leaves it (it lingers while the person is
    already two sensors on), and once its OFF is lost (on for a minute)."""
    site, ids = grid_home()
    rng = np.random.default_rng(seed)
    n = 4
    cell, t, rows, lost = (1, 1), 0.0, [], False
    on_until: dict[str, float] = {}
    while t < minutes * 60.0:
        s = ids[cell]
        stay = float(rng.uniform(10.0, 60.0)) if rng.random() < 1 / 5 else float(rng.uniform(1.0, 3.0))
        hold = float(rng.uniform(2.0, 8.0))
        if not lost and t > 120.0:  # this sensor's OFF is lost: on for a minute more
            hold, lost = 60.0, True
        if t > on_until.get(s, -1.0):  # the sensor was off: an ON edge (and the OFF before it)
            if s in on_until:
                rows.append((on_until[s], s, False))
            rows.append((t, s, True))
        on_until[s] = max(on_until.get(s, -1.0), t + stay + hold)
        t += stay
        di, dj = [(0, 1), (1, 0), (0, -1), (-1, 0)][int(rng.integers(4))]
        cell = (min(max(cell[0] + di, 0), n - 1), min(max(cell[1] + dj, 0), n - 1))
    rows += [(u, s, False) for s, u in on_until.items()]
    return pl.DataFrame(rows, schema=MOTION, orient="row").sort("t"), site


TRACKERS = [
    ("hmm1", run_hmm1, HmmConfig),
    ("hmm2", run_hmm2, HmmConfig),
    ("findinghumo", run_findinghumo, FindingHumoConfig),
    ("findinghumo-flow", run_flow, FlowConfig),
]


@pytest.mark.parametrize("name,run,cfg", TRACKERS, ids=[t[0] for t in TRACKERS])
def test_a_one_resident_log_is_one_user_without_targets(name, run, cfg):
    motion, site = one_resident_log(0)
    lingering = motion.filter("on").height
    assert lingering > 40
    out = run({"motion": motion}, site, cfg())
    assert out["decoder"]["users"][0] == 1, name
    assert out["windows"]["k"].max() == 1  # never a second user inside the decoder either
    # the paper's literal count (every node on) makes the lingering sensors users
    if name == "hmm1":
        literal = run({"motion": motion}, site, cfg(count="on"))
        assert literal["decoder"]["users"][0] > 1


@pytest.mark.parametrize("name,run,cfg", TRACKERS[:2], ids=[t[0] for t in TRACKERS[:2]])
def test_targets_bounds_every_decoding_window(name, run, cfg):
    motion, site = one_resident_log(1)
    free = run({"motion": motion}, site, cfg(count="on"))
    assert free["windows"]["k"].max() > 1  # unbounded, the literal count finds several
    bounded = run({"motion": motion}, dataclasses.replace(site, targets=1), cfg(count="on"))
    assert bounded["windows"]["k"].max() == 1  # the bound holds inside, not only on the output
    assert bounded["decoder"]["users"][0] == 1
