"""The intruder tracker (Schiff & Goldberg): deployment, filter invariants, accuracy, determinism."""

from __future__ import annotations

import math

import numpy as np
import polars as pl
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.core.errors import ConfigError, SiteError
from onebit.core.site import load_site, site_from_dict
from onebit.datasets.pir_sim import fire, path_motion, simulate, site_dict, write_pir_dataset
from onebit.models.motion import Motion, Particles, Room, prior, propagate
from onebit.models.pir import WorldGrid, box_cells, deploy, log_p_silent, sensor_likelihood, sensor_type
from onebit.readers.motion import MotionConfig, read_motion_csv, site_rules
from onebit.scoring.intruder import match_errors
from onebit.trackers.intruder.camera import pan_tilt_zoom
from onebit.trackers.intruder.filter import box_counts, systematic_resample
from onebit.trackers.intruder.stage import IntruderConfig, NaiveConfig, run, run_naive

PAPER_MOTION = Motion(period=2.0, v_max=4.0, speed_sigma=1.5, turn_scale=4.0, max_retries=50)


def run_scenario(tmp_path, scenario, seed, *, refractory=0.0, duration=120.0, **cfg):
    data = write_pir_dataset(
        tmp_path / f"{scenario}-{seed}", scenario, seed=seed, duration=duration, refractory=refractory
    )

    site = load_site(data / "site.toml")
    res = read_motion_csv(
        data / "motion.csv", [m.id for m in site.motion_sensors], rules=site_rules(site, MotionConfig())
    )
    out = run({"motion": res.motion}, site, IntruderConfig(seed=seed, end=duration, **cfg))
    truth = pl.read_csv(data / "truth.csv")
    return site, res, out, truth


# --------------------------------------------------------------------------- accuracy (section VIII-B)


def test_perfect_beams_without_refractory_within_two_cells(tmp_path):
    errors = []
    for seed in (0, 1, 2):
        _, res, out, truth = run_scenario(tmp_path, "beams22", seed)
        assert res.rejects.height == 0 and res.suppressed.height > 0  # the raw log needed the debounce
        sc = match_errors(out["tracks"], truth, tolerance=1.0)
        assert sc.height == 60
        errors.append(sc["error"].to_numpy())
    e = np.concatenate(errors)
    assert (e <= 2.0).mean() >= 0.95


def test_filter_beats_the_naive_baseline_and_degrades_with_refractory(tmp_path):
    means = {}
    for f in (0.0, 16.0):
        _, res, out, truth = run_scenario(tmp_path, "pir14", 5, refractory=f)
        means[f] = match_errors(out["tracks"], truth, tolerance=1.0)["error"].mean()
    naive = run_naive({"motion": res.motion}, site_from_dict(site_dict("pir14")), NaiveConfig(end=120.0))
    naive_mean = match_errors(naive["tracks"], truth, tolerance=1.0)["error"].mean()
    assert means[0.0] < means[16.0] < naive_mean


def test_same_seed_same_tracks(tmp_path):
    _, _, a, _ = run_scenario(tmp_path, "pir8", 3, refractory=4.0, duration=40.0)
    _, _, b, _ = run_scenario(tmp_path, "pir8", 3, refractory=4.0, duration=40.0)
    assert a["tracks"].equals(b["tracks"]) and a["iterations"].equals(b["iterations"])
    site = site_from_dict(site_dict("pir8", 4.0))
    c = run(
        {"motion": read_motion_csv(tmp_path / "pir8-3" / "motion.csv", [m.id for m in site.motion_sensors]).motion},
        site,
        IntruderConfig(seed=4, end=40.0),
    )
    assert not c["tracks"].equals(a["tracks"])


# --------------------------------------------------------------------------- the room constraint

rooms = {
    "square": shapely.box(0, 0, 10, 10),
    "L": shapely.Polygon([(0, 0), (10, 0), (10, 4), (4, 4), (4, 10), (0, 10)]),
    "hole": shapely.box(0, 0, 10, 10).difference(shapely.box(3, 3, 7, 7)),
}


@given(st.sampled_from(sorted(rooms)), st.integers(0, 2**31 - 1), st.integers(1, 3))
@settings(max_examples=30, deadline=None)
def test_no_particle_leaves_the_room(name, seed, retries):
    room = Room(rooms[name])
    rng = np.random.default_rng(seed)
    n = 500
    x, y = room.uniform(n, rng)
    p = Particles(x, y, rng.uniform(0, 2 * math.pi, n), rng.uniform(0, 4.0, n), np.full(n, 1 / n))
    motion = Motion(2.0, 4.0, 1.5, 1.0, retries)
    for _ in range(3):
        p, redraws, clamped = propagate(p, room, motion, rng)
        assert shapely.intersects_xy(rooms[name], p.x, p.y).all()
        assert ((p.v >= 0) & (p.v <= 4.0)).all()
        assert 0 <= clamped <= n


# --------------------------------------------------------------------------- sensor model


def small_site(types: dict, sensors: list[dict]):
    return site_from_dict(
        {
            "name": "t",
            "units": "m",
            "boundary": {"polygon": [[0, 0], [10, 0], [10, 10], [0, 10]]},
            "motion_sensors": sensors,
            "sensor_types": types,
        }
    )


def test_refractory_sensor_contributes_only_its_refractory_probability():
    site = site_from_dict(site_dict("pir14-imperfect", 8.0))
    dep = deploy(site, 1.0)
    rng = np.random.default_rng(0)
    x, y = rng.uniform(0, 10, 300), rng.uniform(0, 10, 300)
    fired = rng.random(14) < 0.5
    blind = np.zeros(14, bool)
    blind[[1, 4, 9]] = True
    lik = sensor_likelihood(x, y, fired, blind, dep, 1.0, 1.0)
    for i in (1, 4, 9):
        want = dep.rho[i] if fired[i] else 1 - dep.rho[i]
        assert np.all(lik[i] == max(want, 1e-12))
    # the same sensors out of refractory depend on the position
    live = sensor_likelihood(x, y, fired, np.zeros(14, bool), dep, 1.0, 1.0)
    assert all(live[i].std() > 0 for i in (1, 4, 9))
    assert np.array_equal(lik[~blind], live[~blind])


@given(st.floats(0.5, 9.5), st.floats(0.5, 9.5), st.floats(0.0, 0.5), st.integers(0, 1000))
@settings(max_examples=50, deadline=None)
def test_silent_probability_is_the_interpolated_product(x, y, h, seed):
    """P(S=0|x) = prod over the xi region cells (q > 0) of L(1-p0, 1-q, V) (brute force over the grid)."""
    rng = np.random.default_rng(seed)
    q = rng.random((10, 10)) * (rng.random((10, 10)) < 0.5)
    samples = [[i + 0.5, j + 0.5, q[j, i]] for j in range(10) for i in range(10) if q[j, i] > 0]
    site = small_site(
        {"g": {"kind": "grid", "samples": samples, "false_positive": h}}, [{"id": "s", "position": [0, 0], "type": "g"}]
    )
    dep = deploy(site, 1.0)
    assert dep.xi[0] == int((dep.q[0] > 0).sum())
    assert dep.p0[0] == pytest.approx(1 - (1 - h) ** (1 / dep.xi[0]))
    p0 = dep.p0[0]
    cells = shapely.box(x - 1, y - 1, x + 1, y + 1)
    prod = 1.0
    for j in range(10):
        for i in range(10):
            if dep.q[0, j, i] == 0:
                continue  # outside the detection region: no influence on the sensor
            V = cells.intersection(shapely.box(i, j, i + 1, j + 1)).area
            qq = max(dep.q[0, j, i], p0)
            prod *= (1 - p0) + V * ((1 - qq) - (1 - p0))
    got = math.exp(log_p_silent(np.array([x]), np.array([y]), dep, 1.0, 1.0)[0, 0])
    assert got == pytest.approx(max(prod, 0.0), abs=1e-9)


@pytest.mark.parametrize("h", [0.0, 0.05, 0.25, 0.6])
def test_empty_room_false_positive_rate_is_h(h):
    """Section VIII-D defines h = P(S_i = 1 | O_1 = ... = O_m = 0, B_i = 0): with the intruder's
    box away from the detection region the sensor fires with probability exactly h, and the
    xi region cells, each with p0 = 1 - (1 - h)^(1/xi), multiply back to it."""
    site = site_from_dict(site_dict("pir14-imperfect"))
    typ = {**site.sensor_types["pir-imperfect"], "false_positive": h}
    site = site_from_dict({**site_dict("pir14-imperfect"), "sensor_types": {"pir-imperfect": typ}})
    dep = deploy(site, 1.0)
    assert np.allclose((1 - dep.p0) ** dep.xi, 1 - h)
    xs, ys = (a.ravel() for a in np.meshgrid(np.arange(1.0, 9.01, 0.25), np.arange(1.0, 9.01, 0.25)))
    p_fire = -np.expm1(log_p_silent(xs, ys, dep, 1.0, 1.0))  # (14, N)
    cx, cy = dep.grid.centres()
    for i in range(14):
        region = dep.q[i] > 0
        far = np.array([not np.any(region & (np.abs(cx - x) < 1.5) & (np.abs(cy - y) < 1.5)) for x, y in zip(xs, ys)])
        assert far.any() and np.allclose(p_fire[i, far], h)
        # inside the region firing is at least as likely as in an empty room, and more when q > p0
        assert np.all(p_fire[i] >= h - 1e-12) and p_fire[i, ~far].max() > h + 0.05


def test_simulated_false_firings_follow_h():
    """The simulator fires with the tracker's model: a sensor whose region the intruder never
    approaches fires in about a fraction h of the iterations (h = 0.25 for pir14-imperfect)."""

    site = site_from_dict(site_dict("pir14-imperfect"))
    dep = deploy(site, 1.0)
    rng = np.random.default_rng(5)
    T = 4000
    xy = np.tile([5.0, 5.0], (T + 1, 1))
    xy[:, 0] = 0.5  # against the left wall, mid-height
    S, _ = fire(rng, xy, dep)
    cx, cy = dep.grid.centres()
    far = [i for i in range(14) if not np.any((dep.q[i] > 0) & (np.abs(cx - 0.5) < 1.5) & (np.abs(cy - 5.0) < 1.5))]
    assert far
    rate = S[:, far].mean(axis=0)
    assert np.all(np.abs(rate - 0.25) < 0.03), rate


def test_simulated_paths_match_the_papers_naive_baseline():
    """Fig. 4: the room-centre estimator is within 4 cells 55 % of the time over the paper's paths.
    The paths come from the paper's intruder model; 2000 of them, 60 steps each, in one array."""

    room = Room(shapely.box(0, 0, 10, 10))
    rng = np.random.default_rng(11)
    p = prior(2000, room, path_motion(), rng)
    d = []
    for _ in range(60):
        p, _, clamped = propagate(p, room, path_motion(), rng)
        assert clamped == 0
        d.append(np.hypot(p.x - 5.0, p.y - 5.0))
    d = np.concatenate(d)
    assert 0.52 <= (d <= 4.0).mean() <= 0.58
    # more central than a uniform position in the room (50 % within 4, mean 3.83)
    assert d.mean() < 3.8


def test_deployment_of_beam_and_triangle():
    site = small_site(
        {},
        [
            {"id": "b", "position": [0, 3.5], "type": "beam"},
            {"id": "p", "position": [5, 0], "heading": 90, "type": "pir"},
        ],
    )
    dep = deploy(site, 1.0)
    beam = dep.q[0]
    assert beam[3].tolist() == [1.0] * 10 and beam.sum() == 10.0
    tri = dep.q[1]
    assert tri.max() == 1.0 and tri.min() == 0.0
    # IDW fills stay within the sample values and only inside the hull of the non-zero cells
    cx, cy = dep.grid.centres()
    assert np.all(shapely.intersects_xy(dep.hulls[1], cx[tri > 0], cy[tri > 0]))
    # rotated by 90 degrees: the triangle opens upwards from cell 5, mirror-symmetric about it
    assert np.allclose(tri[:, 1:10], tri[:, 9:0:-1], atol=1e-9)
    assert tri[:2].sum() < tri[6:9].sum()


def test_sensor_type_errors_name_the_key():
    with pytest.raises(SiteError, match=r"sensor_types.x.colour"):
        sensor_type("x", {"kind": "beam", "colour": 1})
    with pytest.raises(SiteError, match=r"sensor_types.x.false_positive"):
        sensor_type("x", {"kind": "beam", "false_positive": 2.0})
    with pytest.raises(SiteError, match="unknown sensor type"):
        sensor_type("nope")
    with pytest.raises(ConfigError, match="particles"):
        IntruderConfig(particles=0)
    with pytest.raises(ConfigError, match="resample_when"):
        IntruderConfig(resample_when="sometimes")


# --------------------------------------------------------------------------- estimator and resampling


@given(
    st.lists(st.tuples(st.floats(0, 10), st.floats(0, 10)), min_size=1, max_size=40), st.sampled_from([1.0, 2.0, 3.0])
)
@settings(max_examples=60, deadline=None)
def test_box_counts_match_brute_force(pts, width):
    grid = WorldGrid(0.0, 0.0, 1.0, 10, 10)
    xy = np.array(pts)
    w = np.linspace(1, 2, len(xy))
    got = box_counts(xy[:, 0], xy[:, 1], w, grid, width / 2, width / 2)
    cx, cy = grid.centres()
    inside = (np.abs(xy[:, 0][:, None, None] - cx) <= width / 2 + 1e-9) & (
        np.abs(xy[:, 1][:, None, None] - cy) <= width / 2 + 1e-9
    )
    assert np.allclose(got, (inside * w[:, None, None]).sum(axis=0))


@given(st.lists(st.floats(0.0, 1.0), min_size=1, max_size=50), st.integers(0, 1000))
@settings(max_examples=60, deadline=None)
def test_systematic_resampling_counts(weights, seed):
    w = np.array(weights) + 1e-3
    w /= w.sum()
    idx = systematic_resample(w, np.random.default_rng(seed))
    counts = np.bincount(idx, minlength=len(w))
    assert counts.sum() == len(w)
    assert np.all(np.abs(counts - len(w) * w) < 1.0 + 1e-9)


def test_box_cells_cover_the_box_area():
    grid = WorldGrid(0.0, 0.0, 1.0, 10, 10)
    x, y = np.array([5.3, 0.2, 9.9]), np.array([4.7, 0.5, 9.9])
    _, _, V = box_cells(x, y, grid, 1.0, 1.0)
    inside = [
        shapely.box(a - 1, b - 1, a + 1, b + 1).intersection(shapely.box(0, 0, 10, 10)).area for a, b in zip(x, y)
    ]
    assert np.allclose(V.sum(axis=1), inside)


def test_simulated_firings_survive_the_raw_log(tmp_path):
    """The reader recovers exactly the simulator's delivered firings from the chattering log."""
    d, sim = simulate("pir8", seed=2, duration=60.0, refractory=4.0)
    data = write_pir_dataset(tmp_path / "d", "pir8", seed=2, duration=60.0, refractory=4.0)
    site = site_from_dict(d)
    res = read_motion_csv(
        data / "motion.csv", [m.id for m in site.motion_sensors], rules=site_rules(site, MotionConfig())
    )
    on = res.motion.filter(pl.col("on"))
    slots = (on["t"] / 2.0).floor().cast(pl.Int64)
    got = sorted(zip(slots.to_list(), on["sensor"].to_list()))
    want = sorted(zip(sim.firings["slot"].to_list(), sim.firings["sensor"].to_list()))
    assert got == want and res.rejects.height == 0


# --------------------------------------------------------------------------- camera pointing (VII-C)


@given(st.floats(0.5, 9.5), st.floats(0.5, 9.5), st.floats(1.0, 6.0), st.floats(20.0, 90.0))
@settings(max_examples=60, deadline=None)
def test_camera_frames_the_prism_and_no_more(x, y, cz, fov):

    cam = (-1.0, -2.0, cz)
    pan, tilt, zoom = pan_tilt_zoom(np.array([[x, y]]), cam, width=2.0, depth=2.0, height=1.0, fov_deg=fov)[0]
    # pan/tilt point at the prism centre
    f = np.array(
        [
            math.cos(math.radians(tilt)) * math.cos(math.radians(pan)),
            math.cos(math.radians(tilt)) * math.sin(math.radians(pan)),
            math.sin(math.radians(tilt)),
        ]
    )
    d = np.array([x, y, 0.5]) - cam
    assert np.allclose(f, d / np.linalg.norm(d))
    # every corner inside the zoomed field of view, one on its edge
    r = np.cross(f, [0, 0, 1.0])
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    corners = np.array([[x + a, y + b, 0.5 + c * 0.5] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)]) - cam
    xi = np.abs(corners @ r / (corners @ f))
    yi = np.abs(corners @ u / (corners @ f))
    th = math.tan(math.radians(fov) / 2) / zoom
    tv = th / (4 / 3)
    assert np.all(xi <= th + 1e-9) and np.all(yi <= tv + 1e-9)
    assert max(xi.max() / th, yi.max() / tv) == pytest.approx(1.0)


def test_camera_table_from_the_stage(tmp_path):
    site, res, out, _ = run_scenario(tmp_path, "pir8", 1, duration=20.0, camera_position=[0.0, 0.0, 3.0])
    cam = out["camera"]
    assert cam.columns == ["t", "pan", "tilt", "zoom"] and cam.height == 10
    assert (cam["tilt"] < 0).all() and (cam["zoom"] > 0).all()
    with pytest.raises(ConfigError, match="camera_position"):
        IntruderConfig(camera_position=[1.0, 2.0])
