"""``onebit simulate from-truth DATASET_DIR``: the sensor logs a site would record of given walks.

Deployment planning: with real trajectories as ground truth (``onebit import trajectories``
writes ``truth.csv``) and a ``site.toml`` declaring the sensors one considers, this writes
the logs those sensors would produce, so ``onebit run DATASET_DIR`` answers "how well would
this layout track these walks?" with the usual report. It reads ``site.toml`` and
``truth.csv`` of the folder and (re)writes, for the sensors the site has:

* ``beams.csv`` (t, beam, pair, blocked): pair ``p`` of a beam is blocked while the body of
  some target -- a disk of the site's ``body_radius`` (:func:`onebit.core.sensing.body_radius`)
  around its centre -- overlaps the pair's segment, the rule of the beams simulator, so the
  beam reader decodes a crossing when the body has cleared the beam;
* ``motion.csv`` (t, sensor, value): a PIR is triggered while a target's centre is inside its
  detection region (``fov``, ``range``, type extent: :mod:`onebit.core.sensing`), seen in
  each sample with probability ``p_detect``; it turns on at the first trigger, stays on
  ``hold_s`` after the last one, then is blind for its ``refractory`` period (site.toml);
* ``proximity.csv`` (t, sensor, value): on while a target is within ``R_i``; between ``R_i``
  and ``R_o`` (the two-radius model) on with probability ``p_ring``, drawn once per visit of
  the ring;
* ``frames.csv`` (t, active) for ``[[binary_sensors]]`` (a ceiling array read every frame):
  every ``1 / frame_hz`` s (2 Hz), a sensor is active when a target is within its ``R_i``,
  or in the ring up to ``R_o`` with probability ``p_ring`` (drawn per frame), each active
  reading kept with probability ``p_detect``. A site mixing binary sensors with other motion
  or proximity sensors is refused: a run reads the binary readings from one source;
* ``from_truth.toml``: what was simulated (options, seed, counts);
* ``run.toml`` ``[istate]``: what a tracker may know of these sensors and walks, added to the
  folder's own ``run.toml`` where it does not set them already: ``latency_s`` (the PIR's hold
  plus a sample) and ``max_speed`` (the walks' top speed, m/s, +5 %, so the I-state's motion
  model admits every step of the truth).

Positions are interpolated linearly between truth samples on a grid of ``rate_hz`` (20 Hz); a
target is absent across a gap of more than ``max_gap_s`` (2 s) between its samples. ``--drop``
loses a whole pass of a beam, a PIR's or a proximity sensor's whole on-period with that
probability. Log times are on the clock of ``truth.csv`` (numbers as written; ISO stamps need
the site's ``epoch`` and become seconds since it). Vectorised over samples, targets and
sensors; the PIR's refractory rule is sequential over its on-periods (each depends on the
last one kept). Deterministic for a seed.

Options (``--param key=value``): ``rate_hz``, ``max_gap_s``, ``hold_s``, ``p_detect``,
``p_ring``, ``frame_hz``.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import polars as pl
import shapely

from onebit.core.config import check_range
from onebit.core.errors import ConfigError, InputError
from onebit.core.sensing import body_radius, detection_regions
from onebit.core.site import Site, load_site
from onebit.core.units import units_per_metre
from onebit.core.writers import to_toml, write_csv, write_text
from onebit.datasets import kernels
from onebit.datasets.scenario import Scenario
from onebit.models.pir import hold_on
from onebit.readers.tables_csv import read_truth_csv
from onebit.readers.timebase import iso_unix, number

NAME = "from-truth"


@dataclass(frozen=True, kw_only=True)
class FromTruthConfig:
    """Options of the ``from-truth`` simulation (module docstring); seconds and probabilities."""

    rate_hz: float = 20.0
    max_gap_s: float = 2.0
    hold_s: float = 1.0
    p_detect: float = 1.0
    p_ring: float = 0.5
    drop: float = 0.0
    frame_hz: float = 2.0

    def __post_init__(self) -> None:
        for name, lo, hi in (
            ("rate_hz", 1e-3, 1e4),
            ("max_gap_s", 0.0, 1e9),
            ("hold_s", 0.0, 1e6),
            ("p_detect", 0.0, 1.0),
            ("p_ring", 0.0, 1.0),
            ("drop", 0.0, 1.0),
            ("frame_hz", 1e-3, 1e4),
        ):
            check_range(self, name, lo, hi)
        if self.p_detect <= 0:
            raise ConfigError("from-truth: p_detect = 0 would never detect anyone; allowed range: (0, 1]")


# --------------------------------------------------------------------------- positions


def dense_positions(truth: pl.DataFrame, cfg: FromTruthConfig) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """``(times (K,), xy (K, n, 2), targets)``: every target's centre on the common grid of
    ``rate_hz``, NaN where it is absent (before its first sample, after its last, and across
    gaps longer than ``max_gap_s``)."""
    targets = sorted(truth["target"].unique().to_list())
    if truth.height == 0:
        return np.zeros(0), np.zeros((0, 0, 2)), []
    dt = 1.0 / cfg.rate_hz
    t0 = math.floor(float(truth["t"].min()) / dt) * dt
    t1 = float(truth["t"].max())
    times = t0 + np.arange(int(math.floor((t1 - t0) / dt + 1e-9)) + 1) * dt
    xy = np.full((len(times), len(targets), 2), np.nan)
    for j, tgt in enumerate(targets):  # a few targets; each interpolation is vectorised over samples
        tr = truth.filter(pl.col("target") == tgt).sort("t").unique("t", keep="first", maintain_order=True)
        ts, xs, ys = tr["t"].to_numpy(), tr["x"].to_numpy(), tr["y"].to_numpy()
        k = np.searchsorted(ts, times, side="right")  # sample after each grid time
        inside = (times >= ts[0]) & (times <= ts[-1])
        after = np.clip(k, 1, len(ts) - 1)
        gap = np.where(len(ts) > 1, ts[after] - ts[after - 1], 0.0)
        ok = inside & ((gap <= cfg.max_gap_s) | np.isin(times, ts))
        xy[ok, j, 0] = np.interp(times[ok], ts, xs)
        xy[ok, j, 1] = np.interp(times[ok], ts, ys)
    return times, xy, targets


def _runs(on: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end (exclusive) indices of the runs of True in each column of ``on (K, m)``,
    as flat arrays over columns: returns ``(col, start, end)`` stacked in a (3, r) array."""
    K = on.shape[0]
    pad = np.zeros((1, on.shape[1]), dtype=np.int8)
    d = np.diff(np.vstack([pad, on.astype(np.int8), pad]), axis=0)
    s_k, s_c = np.nonzero(d == 1)
    e_k, e_c = np.nonzero(d == -1)
    o_s = np.lexsort((s_k, s_c))
    o_e = np.lexsort((e_k, e_c))
    return np.vstack([s_c[o_s], s_k[o_s], np.minimum(e_k[o_e], K)])


def _drop_runs(on: np.ndarray, rng: np.random.Generator, p: float) -> np.ndarray:
    """``on`` with each run of True (per column) removed with probability ``p``."""
    if p <= 0 or not on.any():
        return on
    col, start, end = _runs(on)
    lost = rng.random(col.size) < p
    out = on.copy()
    delta = np.zeros((on.shape[0] + 1, on.shape[1]), dtype=np.int64)
    np.add.at(delta, (start[lost], col[lost]), 1)
    np.add.at(delta, (end[lost], col[lost]), -1)
    out &= np.cumsum(delta, axis=0)[:-1] == 0
    return out


def _edges(times: np.ndarray, on: np.ndarray, ids: list[str], value: str = "value") -> pl.DataFrame:
    """Toggle edges (t, sensor, value 0|1) of ``on (K, m)``; every sensor starts off."""
    prev = np.vstack([np.zeros((1, on.shape[1]), bool), on[:-1]])
    k, c = np.nonzero(on != prev)
    return pl.DataFrame(
        {
            "t": np.round(times[k], 6),
            "sensor": np.asarray(ids, dtype=object)[c].tolist() if len(c) else [],
            value: on[k, c].astype(np.int8),
        },
        schema={"t": pl.Float64, "sensor": pl.String, value: pl.Int8},
    ).sort("t", "sensor", maintain_order=True)


# --------------------------------------------------------------------------- sensors


def _segment_distance(xy: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of points ``xy (..., 2)`` (NaN stays NaN) to the segment ``a-b``."""
    ab = b - a
    u = np.clip(((xy - a) @ ab) / (ab @ ab), 0.0, 1.0)
    return np.hypot(*np.moveaxis(xy - (a + u[..., None] * ab), -1, 0))


def beam_events(
    site: Site, times: np.ndarray, xy: np.ndarray, cfg: FromTruthConfig, rng: np.random.Generator
) -> pl.DataFrame:
    """Raw pair events of every beam: blocked while a body overlaps the pair (module docstring)."""
    r = body_radius(site)
    parts = []
    for beam in site.beams:  # a few beams; each vectorised over samples and targets
        pairs = beam.pair_segments()
        blocked = {}
        for p, (a, b) in pairs.items():
            d = _segment_distance(xy, a, b)
            blocked[p] = np.nan_to_num(d, nan=np.inf).min(axis=1) < r if xy.shape[1] else np.zeros(len(times), bool)
        both = np.c_[blocked["a"], blocked["b"]]
        passes = _drop_runs(both.any(axis=1)[:, None], rng, cfg.drop)[:, 0]  # a lost pass loses both pairs' events
        both &= passes[:, None]
        ev = _edges(times, both, ["a", "b"], value="blocked").rename({"sensor": "pair"})
        parts.append(ev.with_columns(beam=pl.lit(beam.id)).select("t", "beam", "pair", "blocked"))
    if not parts:
        return pl.DataFrame(schema={"t": pl.Float64, "beam": pl.String, "pair": pl.String, "blocked": pl.Int8})
    return pl.concat(parts).sort("t", "beam", "pair", maintain_order=True)


def pir_events(
    site: Site, times: np.ndarray, xy: np.ndarray, cfg: FromTruthConfig, rng: np.random.Generator
) -> pl.DataFrame:
    """PIR toggles: triggered in the detection region, held ``hold_s``, then refractory."""
    regions = detection_regions(site)
    ids = [m.id for m in site.motion_sensors]
    K, n = xy.shape[0], xy.shape[1]
    flat = xy.reshape(-1, 2)
    present = ~np.isnan(flat[:, 0])
    trig = np.zeros((K, len(ids)), dtype=bool)
    for i, sid in enumerate(ids):  # a few sensors; each vectorised over samples x targets
        inside = np.zeros(K * n, dtype=bool)
        inside[present] = regions[sid].covers_xy(flat[present, 0], flat[present, 1])
        seen = inside & (rng.random(K * n) < cfg.p_detect)
        trig[:, i] = seen.reshape(K, n).any(axis=1)
    on = hold_on(trig, int(round(cfg.hold_s * cfg.rate_hz)) + 1)  # a trigger now or within the last hold_s
    refr = np.array([m.refractory for m in site.motion_sensors], dtype=float)
    if np.any(refr > 0) and on.any():
        col, start, end = _runs(on)
        keep, keep_s = kernels.pir_refractory(col, start, end, times, refr, 1.0 / cfg.rate_hz)
        keep_e = end
        on = np.zeros_like(on)
        delta = np.zeros((K + 1, len(ids)), dtype=np.int64)
        np.add.at(delta, (keep_s[keep], col[keep]), 1)
        np.add.at(delta, (keep_e[keep], col[keep]), -1)
        on = np.cumsum(delta, axis=0)[:-1] > 0
    on = _drop_runs(on, rng, cfg.drop)
    return _edges(times, on, ids)


def proximity_events(
    site: Site, times: np.ndarray, xy: np.ndarray, cfg: FromTruthConfig, rng: np.random.Generator
) -> pl.DataFrame:
    """Proximity toggles: on within ``R_i``; in the ring up to ``R_o`` with probability ``p_ring`` per visit."""
    ps = site.proximity_sensors
    ids = [p.id for p in ps]
    pos = np.array([p.position for p in ps], dtype=float).reshape(-1, 2)
    d = np.hypot(xy[:, :, None, 0] - pos[None, None, :, 0], xy[:, :, None, 1] - pos[None, None, :, 1])  # (K, n, m)
    d = np.nan_to_num(d, nan=np.inf)
    r_in = np.array([p.r_inner for p in ps])
    r_out = np.array([p.r_outer for p in ps])
    sure = (d <= r_in).any(axis=1)
    ring = ((d > r_in) & (d <= r_out)).any(axis=1) & ~sure
    if ring.any() and cfg.p_ring < 1.0:
        col, start, end = _runs(ring)
        lost = rng.random(col.size) >= cfg.p_ring
        delta = np.zeros((ring.shape[0] + 1, ring.shape[1]), dtype=np.int64)
        np.add.at(delta, (start[lost], col[lost]), 1)
        np.add.at(delta, (end[lost], col[lost]), -1)
        ring &= np.cumsum(delta, axis=0)[:-1] == 0
    on = _drop_runs(sure | ring, rng, cfg.drop)
    return _edges(times, on, ids)


def binary_frames(
    site: Site, times: np.ndarray, xy: np.ndarray, cfg: FromTruthConfig, rng: np.random.Generator
) -> pl.DataFrame:
    """``frames.csv`` rows (t, active) of the site's ``[[binary_sensors]]`` (module docstring):
    the dense grid's samples every ``round(rate_hz / frame_hz)`` steps are the frames."""
    bs = site.binary_sensors
    step = max(1, int(round(cfg.rate_hz / cfg.frame_hz)))
    k = np.arange(0, len(times), step)
    pos = np.array([b.position for b in bs], dtype=float).reshape(-1, 2)
    d = np.hypot(xy[k, :, None, 0] - pos[None, None, :, 0], xy[k, :, None, 1] - pos[None, None, :, 1])  # (F, n, m)
    d = np.nan_to_num(d, nan=np.inf)
    r_in = np.array([b.r_inner for b in bs])
    r_out = np.array([b.r_outer for b in bs])
    sure = (d <= r_in).any(axis=1)
    ring = ((d > r_in) & (d <= r_out)).any(axis=1) & ~sure & (rng.random(sure.shape) < cfg.p_ring)
    on = (sure | ring) & (rng.random(sure.shape) < cfg.p_detect)
    ids = np.array([b.id for b in bs], dtype=object)
    active = [" ".join(ids[row]) for row in on]  # one string per frame
    return pl.DataFrame({"t": np.round(times[k], 9), "active": active}, schema={"t": pl.Float64, "active": pl.String})


# --------------------------------------------------------------------------- the folder


def read_truth(dataset: Path, site: Site) -> pl.DataFrame:
    """``truth.csv`` of the folder on its own clock (numbers as written; ISO stamps as seconds
    since the site's epoch, which they then need)."""
    path = dataset / "truth.csv"
    if not path.exists():
        raise InputError("no truth.csv: import trajectories first (onebit import trajectories FILE DIR)", file=path)
    try:
        head = pl.read_csv(path, n_rows=200, infer_schema=False)
    except (pl.exceptions.PolarsError, OSError):
        head = pl.DataFrame()  # the truth reader names what is wrong
    if "t" in head.columns and site.epoch is None:
        iso = head.select((number(pl.col("t")).is_null() & iso_unix(pl.col("t")).is_not_null()).any()).item()
        if iso:
            raise InputError(
                "ISO time stamps need an 'epoch' in site.toml: the logs are written in seconds since it",
                file=path,
                field="t",
            )
    truth, rejects = read_truth_csv(path, epoch=site.epoch)
    if truth.height == 0:
        raise InputError(f"no readable truth row ({rejects.height} rejected)", file=path)
    return truth


def simulate_from_truth(dataset: str | Path, *, seed: int = 0, cfg: FromTruthConfig | None = None) -> dict[str, int]:
    """Write the logs of the folder's sensors from its truth (module docstring); returns counts."""
    dataset = Path(dataset)
    cfg = cfg or FromTruthConfig()
    if not (dataset / "site.toml").exists():
        raise InputError(
            "no site.toml: the folder needs the site (boundary and sensors) to simulate", file=dataset / "site.toml"
        )
    site = load_site(dataset / "site.toml")
    if not (site.beams or site.motion_sensors or site.proximity_sensors):
        raise InputError(
            "the site declares no sensor (beams, motion_sensors, proximity_sensors) to simulate",
            file=dataset / "site.toml",
        )
    if (
        site.binary_sensors
        and (set(m.id for m in site.motion_sensors) | set(p.id for p in site.proximity_sensors)) - site.binary_ids
    ):
        raise InputError(
            "the site mixes [[binary_sensors]] with other motion or proximity sensors: a run reads the binary readings "
            "from one source (frames.csv), so declare them all as binary sensors or none",
            file=dataset / "site.toml",
            field="binary_sensors",
        )
    truth = read_truth(dataset, site)
    rng = np.random.default_rng(seed)
    times, xy, targets = dense_positions(truth, cfg)
    outside = ~np.isnan(xy[:, :, 0]) & ~shapely.contains_xy(
        site.boundary.buffer(1e-9), np.nan_to_num(xy[:, :, 0]), np.nan_to_num(xy[:, :, 1])
    )
    counts = {"targets": len(targets), "samples": int(len(times)), "outside_boundary": int(outside.sum())}
    if site.beams:
        ev = beam_events(site, times, xy, cfg, rng)
        write_csv(ev, dataset / "beams.csv")
        counts["beam_events"] = ev.height
    if site.binary_sensors:
        fr = binary_frames(site, times, xy, cfg, rng)
        write_csv(fr, dataset / "frames.csv")
        counts["frames"] = fr.height
    elif site.motion_sensors:
        ev = pir_events(site, times, xy, cfg, rng)
        write_csv(ev, dataset / "motion.csv")
        counts["motion_edges"] = ev.height
    if site.proximity_sensors and not site.binary_sensors:
        ev = proximity_events(site, times, xy, cfg, rng)
        write_csv(ev, dataset / "proximity.csv")
        counts["proximity_edges"] = ev.height
    known = tracker_knowledge(times, xy, site, cfg)
    update_run_toml(dataset / "run.toml", {"istate": known})
    doc = {
        "simulated": {"scenario": NAME, "seed": seed, "body_radius": body_radius(site), "units": site.units},
        "options": asdict(cfg),
        "counts": counts,
    }
    write_text(to_toml(doc), dataset / "from_truth.toml")
    return counts


def tracker_knowledge(times: np.ndarray, xy: np.ndarray, site: Site, cfg: FromTruthConfig) -> dict:
    """``[istate]`` values a tracker may know: ``latency_s`` and ``max_speed`` (m/s)."""
    out = {"latency_s": round(cfg.hold_s + 1.0 / cfg.rate_hz, 6)}
    if len(times) > 1 and xy.shape[1]:
        step = np.hypot(*np.moveaxis(np.diff(xy, axis=0), -1, 0)) / np.diff(times)[:, None]  # (K-1, n), NaN when absent
        top = float(np.nanmax(step)) if np.isfinite(step).any() else 0.0
        top_m = top / units_per_metre(site.units)
        out["max_speed"] = max(0.1, math.ceil(top_m * 1.05 * 10) / 10)
    return out


def update_run_toml(path: Path, sections: dict[str, dict]) -> None:
    """Add ``sections`` to the folder's ``run.toml``, keeping every value it already sets."""
    data = {}
    if path.exists():
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise InputError(f"not valid TOML: {exc}", file=path) from None
    for name, values in sections.items():
        table = data.setdefault(name, {})
        if not isinstance(table, dict):
            raise InputError(f"[{name}] must be a table", file=path, field=name)
        for k, v in values.items():
            table.setdefault(k, v)
    write_text("# Known conditions of this dataset (written by onebit; edit freely)\n" + to_toml(data), path)


def _float(params: dict, key: str, default: float) -> float:
    if key not in params:
        return default
    try:
        return float(params[key])
    except ValueError:
        raise ConfigError(f"--param {key}={params[key]!r}: expected a number") from None


def _write(
    dataset,
    *,
    seed: int,
    duration=None,
    agents=None,
    drop: float = 0.0,
    camera: bool = False,
    params: dict | None = None,
) -> Path:
    params = dict(params or {})
    known = ("rate_hz", "max_gap_s", "hold_s", "p_detect", "p_ring", "frame_hz")
    unknown = sorted(set(params) - set(known))
    if unknown:
        raise ConfigError(f"scenario {NAME!r}: unknown --param {unknown}; known: {list(known)}")
    if duration is not None or agents is not None:
        raise ConfigError(f"scenario {NAME!r}: the truth sets the duration and the targets; drop --duration/--agents")
    cfg = FromTruthConfig(**{k: _float(params, k, getattr(FromTruthConfig, k)) for k in known}, drop=float(drop or 0.0))
    simulate_from_truth(dataset, seed=seed, cfg=cfg)
    return Path(dataset)


SCENARIO_SPECS = {
    NAME: Scenario(
        NAME,
        "the logs of the folder's site.toml sensors (beams with body width, PIR fov/refractory, proximity, binary frames) from its truth.csv",
        _write,
    )
}
