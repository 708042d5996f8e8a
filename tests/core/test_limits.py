"""Config values that size an allocation are bounded (#26 item 8): past a limit of
:mod:`onebit.core.config` the error names the field, never a MemoryError or an abort."""

from __future__ import annotations

import numpy as np
import polars as pl
import pytest

from onebit.core.config import MAX_STEPS, check_size
from onebit.core.errors import ConfigError
from onebit.core.frames import motion_frames
from onebit.core.tables import MOTION
from onebit.models.pir import WorldGrid
from onebit.readers.proximity import ProximityConfig, proximity_frames
from onebit.trackers.binpf.stage import BinPFConfig
from onebit.trackers.clustertrack.feasible import make_raster
from onebit.trackers.intruder.stage import IntruderConfig
from onebit.trackers.istate.stage import IStateConfig


def _edges(ts, sensor="s1"):
    return pl.DataFrame({"t": ts, "sensor": [sensor] * len(ts), "on": [True, False] * (len(ts) // 2)}, schema=MOTION)


def test_check_size_names_the_field_and_the_limit():
    check_size(10, 10, what="rows", field="[x] n")
    with pytest.raises(ConfigError, match=r"^\[x\] n: 11 rows, more than the 10 onebit allows; smaller$"):
        check_size(11, 10, what="rows", field="[x] n", hint="smaller")
    with pytest.raises(ConfigError, match="nan rows"):
        check_size(float("nan"), 10, what="rows", field="[x] n")


def test_instants_are_bounded_at_load():
    """``[proximity] instants = 10000000000`` aborted the process in the allocator."""
    assert ProximityConfig(instants=MAX_STEPS).instants == MAX_STEPS
    with pytest.raises(ConfigError, match=r"ProximityConfig\.instants = 10000000000; allowed range: \[0, 10000000\]"):
        ProximityConfig(instants=10**10)


def test_proximity_frames_refuse_more_rows_than_the_limit():
    ev = _edges([0.0, 100.0])
    assert proximity_frames(ev, ["s1", "s2"], period=1.0).height == 2 * 101
    with pytest.raises(ConfigError, match=r"\[proximity\] period = 1 s / instants: 40,000,000 frame rows"):
        proximity_frames(ev, ["s1", "s2"], period=1.0, instants=20_000_000)
    with pytest.raises(ConfigError, match=r"\[proximity\] period = 1e-06 s: 100,000,000 instants"):
        proximity_frames(ev, ["s1"], period=1e-6)


def test_motion_frames_refuse_a_period_too_short_for_the_span():
    ev = _edges([0.0, 50.0])
    assert motion_frames(ev, ["s1", "s2"], period=1.0).height == 2 * 51
    with pytest.raises(ConfigError, match=r"period = 1e-06 s: 100,000,002 frame rows"):
        motion_frames(ev, ["s1", "s2"], period=1e-6)
    with pytest.raises(ConfigError, match=r"period = 1e-06 s"):
        motion_frames(ev, ["s1", "s2"], period=1e-6, t0=0.0, t1=50.0)


def test_world_grid_and_raster_refuse_a_cell_too_small(lab):
    site, _ = lab
    grid = WorldGrid.of_site(site, 0.5)
    assert grid.nx * grid.ny > 0
    with pytest.raises(ConfigError, match=r"cell = 1e-05: .* grid cells"):
        WorldGrid.of_site(site, 1e-5)
    with pytest.raises(ConfigError, match=r"\[clustertrack\] raster_per_r: .* raster cells"):
        make_raster(site.boundary, 1e-5)


def test_particle_and_stage_counts_are_bounded():
    with pytest.raises(ConfigError, match=r"IntruderConfig\.particles = 100000000"):
        IntruderConfig(particles=10**8)
    with pytest.raises(ConfigError, match=r"IntruderConfig\.log_particles"):
        IntruderConfig(log_particles=10**8)
    with pytest.raises(ConfigError, match=r"IStateConfig\.max_stages = 100000000"):
        IStateConfig(max_stages=10**8)
    assert BinPFConfig(particles=10**6, max_tracks=10).particles == 10**6  # the product is checked at the run


def test_clustertrack_kept_and_candidate_particles_are_bounded():
    """K kept particles carry a (K, K) matrix of summed distances; K x m_t candidates are drawn."""
    from shapely.geometry import box

    from onebit.trackers.clustertrack.algorithm import cluster_track, rules_of_thumb
    from onebit.trackers.clustertrack.feasible import SensorArray
    from onebit.trackers.clustertrack.space import FeasibleSpace

    xy = np.array([[0.5, 0.5], [1.5, 0.5]])
    sa = SensorArray(("a", "b"), xy, np.ones(2), np.ones(2))
    on = np.array([[1, 0], [1, 1], [0, 1]], dtype=bool)
    space = FeasibleSpace.build(on, np.arange(3, dtype=float), sa, box(0, 0, 2, 1), dim=2, cell=0.1)
    assert rules_of_thumb(space, H=50, m_o=50.0).K == 50
    with pytest.raises(ConfigError, match=r"\[clustertrack\] k \(default h x q_hat\): 100,000,000 particle pairs"):
        rules_of_thumb(space, H=50, m_o=50.0, K=10_000)
    p = rules_of_thumb(space, H=50, m_o=10**9)
    with pytest.raises(ConfigError, match=r"\[clustertrack\] m_o_r / m_o_r2: .* candidate particles"):
        cluster_track(space, p, np.random.default_rng(0))


def test_scores_gates_are_bounded():
    from onebit.scoring.crossings import MAX_GATES, ScoresConfig

    assert len(ScoresConfig(gates_m=[float(g + 1) for g in range(MAX_GATES)]).gates_m) == MAX_GATES
    with pytest.raises(ConfigError, match="ScoresConfig.gates_m: 33 gates, more than the 32"):
        ScoresConfig(gates_m=[float(g + 1) for g in range(33)])


def test_beams_correction_count_states_are_bounded():
    """With no known start every count vector of n agents over p regions is a start state:
    C(n + p - 1, p - 1) of them ([correct] n = 10^9 was a 7.45 GiB allocation)."""
    from onebit.trackers.beams.correction import CorrectConfig
    from onebit.trackers.beams.counting import RegionEdges, correct

    with pytest.raises(ConfigError, match=r"CorrectConfig\.n = 1000000000; allowed range: \[1, 10000\]"):
        CorrectConfig(n=10**9)
    e = RegionEdges.from_arrays([0, 1, 2, 3, 4], [1, 2, 3, 4, 5], 6)
    src, tgt = e.edge_source[[0, 1]], e.edge_target[[0, 1]]
    assert correct(src, tgt, e, n_agents=3).cost == 0
    with pytest.raises(ConfigError, match=r"\[correct\] n \(or site\.toml targets\): .* count-state cells"):
        correct(src, tgt, e, n_agents=1000)


def test_site_targets_are_bounded(tmp_path):
    from onebit.core.errors import SiteError
    from onebit.core.site import load_site
    from onebit.datasets.builtin import builtin_site_path

    text = builtin_site_path("lab").read_text()
    assert "targets" not in text.split("[", 1)[0]
    (tmp_path / "site.toml").write_text("targets = 100000\n" + text)
    with pytest.raises(SiteError, match=r"targets.*must be an integer in \[0, 10000\], got 100000"):
        load_site(tmp_path / "site.toml")
