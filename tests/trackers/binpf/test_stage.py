"""The binpf stage: frames in, tracks out in the canonical schema, the site's targets bound,
the count reported per frame, config errors naming the field."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from onebit.core.errors import ConfigError
from onebit.core.site import site_from_dict
from onebit.core.tables import FRAMES, TRACKS
from onebit.scoring.binpf import score, true_counts
from onebit.trackers.binpf.filter import frame_probability_off
from onebit.trackers.binpf.stage import BinPFConfig, run

XY = np.array([(1.0 + 1.5 * i, 1.0 + 1.5 * j) for i in range(5) for j in range(3)])


def _site(targets: int | None):
    d = {
        "units": "m",
        "boundary": {"polygon": [[0, 0], [8, 0], [8, 5], [0, 5]]},
        "binary_sensors": [{"id": f"s{k}", "position": list(p), "radius": 1.0} for k, p in enumerate(XY)],
    }
    if targets is not None:
        d["targets"] = targets
    return site_from_dict(d)


def _frames(T=40, seed=0):
    """Three people walking along the rows; levels drawn from the noisy-OR model."""
    rng = np.random.default_rng(seed)
    u = np.linspace(0.5, 7.5, T)
    people = np.stack([np.c_[u, np.full(T, 1.0)], np.c_[u[::-1], np.full(T, 2.5)], np.c_[u, np.full(T, 4.0)]], axis=1)
    p_off = np.stack(
        [frame_probability_off(people[k], XY, np.ones(len(XY)), pd=0.9, pf=0.005, edge=0.2) for k in range(T)]
    )
    on = rng.random(p_off.shape) > p_off
    S = len(XY)
    frames = pl.DataFrame(
        {
            "slot": np.repeat(np.arange(T), S),
            "t": np.repeat(np.arange(T) * 0.5, S),
            "sensor": [f"s{k}" for k in range(S)] * T,
            "on": on.ravel(),
            "fired": on.ravel(),
        },
        schema=FRAMES,
    )
    truth = pl.DataFrame(
        {
            "t": np.repeat(np.arange(T) * 0.5, 3),
            "target": ["a", "b", "c"] * T,
            "x": people[:, :, 0].ravel(),
            "y": people[:, :, 1].ravel(),
        }
    )
    return frames, truth


@pytest.mark.parametrize("targets", [3, 2, 1])
def test_never_more_tracks_at_once_than_targets(targets):
    frames, truth = _frames()
    out = run({"proximity_frames": frames}, _site(targets), BinPFConfig(particles=100))
    assert out["tracks"].schema == TRACKS and out["tracks"].height > 0
    assert out["tracks"].group_by("t").len()["len"].max() <= targets
    assert out["frames"]["reported"].max() <= targets
    rows, tables = score(
        "binpf", {"binpf_frames": out["frames"], "binpf_tracks": out["tracks"], "truth": truth}, _site(targets)
    )
    m = {r[1]: r[2] for r in rows}
    assert m["max_reported"] <= targets and m["filter_count_error"] >= 0


def test_three_walkers_counted_and_followed():
    frames, truth = _frames()
    out = run({"proximity_frames": frames}, _site(None), BinPFConfig(particles=150))
    rows, _ = score(
        "binpf", {"binpf_frames": out["frames"], "binpf_tracks": out["tracks"], "truth": truth}, _site(None)
    )
    m = {r[1]: r[2] for r in rows}
    assert m["filter_count_error"] <= 0.6
    tr = out["tracks"].filter(pl.col("t") >= 5.0)
    hits = 0
    for (t,), g in tr.group_by(["t"]):
        p = truth.filter(pl.col("t") == t).select("x", "y").to_numpy()
        e = g.select("x", "y").to_numpy()
        hits += int((np.sqrt(((p[:, None] - e[None]) ** 2).sum(-1)).min(axis=1) <= 1.0).sum())
    assert hits >= 0.6 * 3 * truth.filter(pl.col("t") >= 5.0)["t"].n_unique()


def test_true_counts_take_every_frame_including_empty_ones():
    t = np.arange(6) * 0.5
    truth = pl.DataFrame({"t": [0.5, 0.5, 1.5], "target": ["a", "b", "a"], "x": [0.0] * 3, "y": [0.0] * 3})
    assert true_counts(t, truth).tolist() == [0, 2, 0, 1, 0, 0]


def test_config_errors_name_the_field():
    with pytest.raises(ConfigError, match="r_delete"):
        BinPFConfig(r_confirm=0.5, r_delete=0.6)
    with pytest.raises(ConfigError, match="pd"):
        BinPFConfig(pd=1.5)
    with pytest.raises(ConfigError, match="count_ratio"):  # the online driver has no count
        BinPFConfig(count_ratio=3.0, commit_lag=6)
    with pytest.raises(ConfigError, match="count_ratio"):
        BinPFConfig(count_ratio=-1.0)


def test_particles_sent_to_rerun_stay_within_the_budget_and_never_change_the_tracks():
    frames, _ = _frames(T=30)
    full = run({"proximity_frames": frames}, _site(3), BinPFConfig(particles=60, log_particles=20))
    cut = run(
        {"proximity_frames": frames},
        _site(3),
        BinPFConfig(particles=60, log_particles=20, log_particles_max=30 * 4 * 5),
    )
    per = {
        k: np.unique(v["artifacts"]["particles_t"], return_counts=True)[1] for k, v in (("full", full), ("cut", cut))
    }
    live = full["frames"].filter(pl.col("live") > 0)["live"].to_numpy()
    assert per["full"].tolist() == (20 * live).tolist() and per["cut"].tolist() == (5 * live).tolist()
    assert full["tracks"].equals(cut["tracks"]) and full["existence"].equals(cut["existence"])
