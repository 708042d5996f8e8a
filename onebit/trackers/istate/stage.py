"""The ``istate`` stage: binary sensors of known sensing regions -> O'Kane I-states per stage.

The dataset's sensors are treated as fixed trackers that share one I-state (they always
communicate); each senses its detection region of the site (:mod:`onebit.core.sensing`: a
motion sensor's ``fov``, ``range`` disk and type extent intersected, a proximity sensor's
disk of radius ``R_o``, a beam as a thin region -- the segment grown by how far a body's
centre can be from it at a crossing, half its pair spacing plus the site's body radius
(:func:`onebit.readers.beams.crossing_reach`), plus ``beam_width``). Lengths and speeds of the config are in metres (m/s)
and reach the stage in the site's units (:func:`onebit.core.units.config_in_site_units`).
Readings are sampled at stage times ``t_k = k T`` (``T = period_s``) and the filter of
:mod:`onebit.trackers.istate.core` runs.

Sampling (our formulation; the paper has discrete stages already). A sensor contributes a
detection at stage ``k``

* when it is on at ``t_k``: region ``S (+) B(v latency_s)`` (``v = max_speed``; ``latency_s`` is
  how long a reading may lag the target: the log's sampling interval, a hold time; 0 for
  ideal continuous-time sensors);
* when it was on during ``(t_{k-1}, t_k]`` but is off at ``t_k``: it went off at ``t_off``,
  so a target was in ``S`` just before ``t_off`` and is now within ``v (t_k - t_off + latency_s)``
  of it -- region ``S (+) B(v (t_k - t_off + latency_s))``;
* a crossing of a beam at ``t_c in (t_{k-1}, t_k]``: region ``beam (+) B(v (t_k - t_c))``.

Each region is clipped to the free space. A reading 0 carries no information (the paper's
model: false negatives are possible), unless ``reliable_negatives`` is set: then a motion
sensor off at ``t_k`` (with no edge in the stage) removes its region and a proximity sensor
off removes its inner disk ``R_i``, each eroded by ``v latency_s`` (beyond the paper).
``latency_s`` is by default raised to the logs' time resolution (``latency_auto``).
Readings are first reduced to edges, so level-sampled logs work too. The loop over stages
is inherently sequential; every stage's geometry is vectorised in :mod:`core`.

Units. The filter runs in the site's normalised frame (:class:`~onebit.trackers.istate.core.SiteFrame`):
the free space and the sensing regions mapped to ``(x - origin) / L`` and snapped to a
``2^-20`` grid (each grown by a grid step, a cleared region shrunk by one, every length
rounded up: still supersets), so the same site in cm and in m is the same computation bit
for bit; regions, areas and the point summary are mapped back to site units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import polars as pl
import shapely

from onebit.core.config import MAX_STEPS, check_size
from onebit.core.errors import ConfigError
from onebit.core.frames import ABSENT_AFTER_S, outside_silence, silent_stretches
from onebit.core.lazy import lazy_module
from onebit.core.params import param, validate
from onebit.core.sensing import body_radius, detection_regions
from onebit.core.site import Site
from onebit.core.tables import CROSSINGS, MOTION, PROXIMITY, TRACKS, check_schema, conform
from onebit.core.units import length
from onebit.core.wkb import wkb_column
from onebit.trackers.base import ARTIFACTS, TrackerSpec
from onebit.trackers.istate.core import (
    SHAPES,
    IState,
    PairMemo,
    SiteFrame,
    disk,
    grow,
    info_state_update,
    shrink,
)

_optimize = lazy_module("scipy.optimize")

NAME = "istate"

#: Schema of ``istate_regions``: every region of every element at every stage (WKB).
REGIONS = pl.Schema(
    {"t": pl.Float64, "stage": pl.Int64, "element": pl.Int64, "k": pl.Int64, "area": pl.Float64, "wkb": pl.Binary}
)
#: Schema of ``istate_summary``: one row per stage.
SUMMARY = pl.Schema(
    {
        "t": pl.Float64,
        "stage": pl.Int64,
        "elements": pl.Int64,
        "area": pl.Float64,
        "detections": pl.Int64,
        "rejected": pl.Int64,
        "area_share": pl.Float64,
    }
)
#: Schema of ``istate_detections``: the sensing regions with reading 1 used at each stage.
DETECTIONS = pl.Schema({"t": pl.Float64, "stage": pl.Int64, "sensor": pl.String, "inflation": pl.Float64})


@dataclass(frozen=True, kw_only=True)
class IStateConfig:
    """Configuration of the ``istate`` tracker (``[istate]`` in ``run.toml``)."""

    period_s: float = param(1.0, "stage period T (readings are sampled at t_k = k T)", lo=1e-6, unit="s")
    max_speed: float = length(
        1.5, "largest target speed (converted to site units per second); s_tgt = max_speed * T", unit="m/s", lo=0.0
    )
    targets: int = param(
        0,
        "number of targets n; 0 = the site's targets (the stage runs only on sites that declare targets; "
        "this overrides it)",
        lo=0,
        hi=8,
    )
    max_elements: int = param(10, "the cap M on the number of elements (paper: 10); 0 = no cap", lo=0, hi=10_000)
    shape: str = param(
        "exact",
        "exact polygons, or the over-approximation by rect (axis-aligned rectangles, the paper's "
        "simulations) or disk (section VI-A.1)",
        choices=SHAPES,
    )
    reliable_negatives: bool = param(
        False, "readings 0 remove the sensing region (sensors without false negatives; beyond the paper)"
    )
    latency_s: float = param(
        0.0,
        "how late a sensor's reading may lag the target: an off edge may come up to this long after the "
        "target left, an on state may hold this long after it (the sampling interval of the log, a PIR "
        "hold time); 0 = ideal continuous-time sensors",
        lo=0.0,
        unit="s",
    )
    latency_auto: bool = param(
        True,
        "use max(latency_s, resolution), where the resolution is the smallest positive gap between distinct "
        "reading times of the motion/proximity logs (0.1 s for a 10 Hz log, 1 s for readings at whole seconds)",
    )
    beam_width: float = length(
        0.0,
        "extra half-width of a beam's region, beyond its reach at a crossing (half its pair spacing plus the "
        "site's body_radius: a crossing is logged when the body has cleared the beam, its centre that far past it)",
        lo=0.0,
    )
    substeps: int = param(
        1, "rounds of grow-and-clip in the motion update (more follow obstacles tighter)", lo=1, hi=100
    )
    absent_after: float = param(
        ABSENT_AFTER_S,
        "the empty room: no point summary (track row) inside a stretch this long in which every sensor is "
        "off and nothing happens; 0 = always one. The I-state itself is unchanged",
        lo=0.0,
        hi=1e12,
        unit="s",
    )
    max_stages: int = param(
        500_000,
        "the most stages (span / period_s) the pipeline runs the filter on; a longer log skips the stage, "
        "saying so. 500 000 holds 5.8 days at 1 s and the 10^6-row beams log (461 733 stages). A stage whose "
        "I-state and readings were met before is looked up (a few microseconds), a new one is computed "
        "(0.1-0.7 ms: 0.13 ms on a simulated 100 000 s beams log, 23 % of its stages computed; 0.5-0.7 ms in "
        "a two-resident home, 15 %), and the recording adds ~10 us a stage. Measured: the 10^6-row beams log "
        "(tiled, 117 stages computed) 1.5 s of filter, its default run 12 s; a simulated day of the home, "
        "86 389 stages, 18-22 s of filter. A log of new stages only would cost up to ~0.7 ms x 500 000 = "
        "6 min. 0 = no bound but MAX_STEPS (10 million; more is refused, as a larger max_stages is)",
        lo=0,
        hi=MAX_STEPS,
    )
    contradictions: str = param(
        "reject",
        "what a reading that no joint state explains does (a spurious or late firing, a footprint larger "
        "than declared): reject keeps the I-state and counts the reading (summary.rejected); empty is the "
        "paper's filter, whose I-state then stays empty for the rest of the run",
        choices=("reject", "empty"),
    )

    def __post_init__(self) -> None:
        validate(self)


# --------------------------------------------------------------------------- sensing regions


@dataclass(frozen=True)
class SensingRegions:
    """Sensing region of every sensor id (superset of where a reading 1 can come from) and,
    for ``reliable_negatives``, the region a reading 0 clears (a subset of it)."""

    ids: tuple[str, ...]
    positive: np.ndarray  # (r,) geometries
    negative: np.ndarray  # (r,) geometries, empty where a 0 says nothing
    kind: tuple[str, ...]


def sensing_regions(site: Site, config: IStateConfig) -> SensingRegions:
    """The sensing regions of every sensor, from the site's detection regions
    (:func:`onebit.core.sensing.detection_regions`: a motion sensor's ``fov``, ``range`` disk
    and type extent intersected; a proximity sensor's disk ``R_o``; a beam's segment grown by
    half its pair spacing), as polygons that contain them (round parts grown by the
    circumscribing radius, :func:`~onebit.trackers.istate.core.grow`), a beam's grown further
    by the site's body radius (where the centre is when the crossing is logged) and ``beam_width``. Negatives clear a subset: a motion sensor's region with its disk
    inscribed, a proximity sensor's inscribed disk ``R_i``, a binary sensor's (``[[binary_sensors]]``)
    inscribed disk ``R_i`` within its ``fov``; a beam clears nothing. A motion
    sensor without a usable region raises :class:`~onebit.core.errors.SiteError`."""
    ids, pos, neg, kind = [], [], [], []
    for r in detection_regions(site).values():
        polys = [g for g in (r.fov, r.extent) if g is not None]
        extra = body_radius(site) + config.beam_width if r.kind == "beam" else 0.0
        outer = polys + ([grow(r.core, r.radius + extra)] if r.radius is not None else [])
        ids.append(r.sensor), kind.append(r.kind), pos.append(_intersect(outer))
        if r.kind == "motion":
            neg.append(_intersect(polys + ([disk(r.position, r.radius, outer=False)] if r.radius is not None else [])))
        elif r.kind == "proximity" and r.inner_radius:
            neg.append(disk(r.position, r.inner_radius, outer=False))
        elif r.kind == "binary" and r.inner_radius:  # a binary sensor's 0 clears its inner disk R_i (within its fov)
            neg.append(_intersect(polys + [disk(r.position, r.inner_radius, outer=False)]))
        else:
            neg.append(shapely.Polygon())
    obj = lambda xs: np.array(xs + [None], dtype=object)[:-1]  # noqa: E731 -- 1-d object array
    return SensingRegions(tuple(ids), obj(pos), obj(neg), tuple(kind))


def _intersect(parts: list):
    out = parts[0]
    for g in parts[1:]:
        out = shapely.intersection(out, g)
    return out


def available(site: Site) -> str | None:
    if not (site.motion_sensors or site.proximity_sensors or site.beams):
        return "site has no binary sensors (motion, proximity, beams)"
    if site.targets is None:
        return "site.toml does not give the number of targets ('targets'); the I-state is over W^n"
    return None


def fits(inputs: dict, site: Site, config: IStateConfig) -> str | None:
    """Reason to skip the filter on these inputs, or ``None``: the stages ``k T`` from the first
    to the last reading (:func:`stage_times`) exceed ``config.max_stages`` (0 = no bound but
    :data:`~onebit.core.config.MAX_STEPS`, past which it is a :class:`ConfigError`)."""
    ts = [inputs[k]["t"] for k in ("motion", "proximity", "crossings") if k in inputs and inputs[k].height]
    if not ts:
        return None
    lo, hi = float(min(t.min() for t in ts)), float(max(t.max() for t in ts))
    stages = np.ceil(hi / config.period_s - 1e-9) - np.floor(lo / config.period_s + 1e-9) + 1
    check_size(stages, MAX_STEPS, what="stages over the logs", field=f"[istate] period_s = {config.period_s:g}")
    stages = int(stages)
    if not config.max_stages or stages <= config.max_stages:
        return None
    return (
        f"the logs span {hi - lo:,.0f} s = {stages:,} stages of period_s = {config.period_s:g} s, more than "
        f"max_stages = {config.max_stages:,} (the filter costs 0.1-0.7 ms per stage it computes, a few us per stage "
        "whose I-state and readings recur, its recording ~10 us); "
        "set [istate] max_stages = 0 (no bound) or a longer period_s in --config to run it"
    )


# --------------------------------------------------------------------------- sampling


def stage_times(tables: list[pl.DataFrame], period: float) -> np.ndarray:
    """Stage times ``k T`` from the first to the last reading (aligned to multiples of ``T``)."""
    ts = [df["t"] for df in tables if df.height]
    if not ts:
        return np.zeros(0)
    lo, hi = float(min(t.min() for t in ts)), float(max(t.max() for t in ts))
    k0, k1 = int(np.floor(lo / period + 1e-9)), int(np.ceil(hi / period - 1e-9))
    return np.arange(k0, k1 + 1) * period


def time_resolution(t: pl.Series) -> float:
    """Smallest positive gap between distinct reading times (0 for fewer than two)."""
    u = t.unique().sort().diff().drop_nulls()
    u = u.filter(u > 1e-9)
    return float(u.min()) if len(u) else 0.0


def _stage_index(t: pl.Expr, t0: float, period: float) -> pl.Expr:
    """Stage k with ``t in (t_{k-1}, t_k]`` (index from the first stage time t0)."""
    return ((t - t0) / period - 1e-9).ceil().cast(pl.Int64).clip(0, None)


def state_readings(edges: pl.DataFrame, times: np.ndarray, period: float, hold: float, speed: float) -> pl.DataFrame:
    """Detections and negatives of on/off sensors at stage times.

    ``edges`` (t, sensor, on): edges or level readings (repeated states are dropped). Returns (stage, sensor, detect, inflation, negative): ``detect``
    when on at ``t_k`` (inflation ``v hold``) or on during the stage (inflation
    ``v (t_k - t_off + hold)``); ``negative`` when off at ``t_k`` with no edge in the stage.
    Vectorised with polars over sensors x stages.
    """
    if edges.height == 0 or len(times) == 0:
        return pl.DataFrame(
            schema={
                "stage": pl.Int64,
                "sensor": pl.String,
                "detect": pl.Boolean,
                "inflation": pl.Float64,
                "negative": pl.Boolean,
            }
        )
    t0 = float(times[0])
    # readings -> edges: keep a row only where the sensor's state changes (every sensor starts
    # off), so level-sampled tables (a row per reading) and edge tables are treated alike
    e = (
        edges.sort("t", maintain_order=True)
        .filter(pl.col("on") != pl.col("on").shift(1, fill_value=False).over("sensor"))
        .with_columns(stage=_stage_index(pl.col("t"), t0, period))
    )
    per = e.group_by("sensor", "stage").agg(
        last_on=pl.col("on").last(),
        n_edges=pl.len(),
        t_off=pl.col("t").filter(~pl.col("on")).max(),
    )
    grid = pl.DataFrame({"sensor": edges["sensor"].unique().sort()}).join(
        pl.DataFrame({"stage": np.arange(len(times), dtype=np.int64), "tk": times}), how="cross"
    )
    g = (
        grid.join(per, on=["sensor", "stage"], how="left")
        .sort("sensor", "stage")
        .with_columns(
            state=pl.col("last_on").forward_fill().over("sensor").fill_null(False),
            n_edges=pl.col("n_edges").fill_null(0),
        )
    )
    on_during = (pl.col("n_edges") > 0) & pl.col("t_off").is_not_null()
    return g.select(
        "stage",
        "sensor",
        detect=pl.col("state") | on_during,
        inflation=pl.when(pl.col("state"))
        .then(speed * hold)
        .otherwise(speed * (pl.col("tk") - pl.col("t_off") + hold)),
        negative=~pl.col("state") & (pl.col("n_edges") == 0),
    )


def crossing_readings(
    crossings: pl.DataFrame, times: np.ndarray, period: float, speed: float, hold: float = 0.0
) -> pl.DataFrame:
    """Beam detections: the latest crossing of each beam in each stage, inflated by
    ``v (t_k - t_c + hold)`` (``hold``: how late the crossing's stamp may be, the raw log's
    sampling interval)."""
    if crossings.height == 0 or len(times) == 0:
        return pl.DataFrame(
            schema={
                "stage": pl.Int64,
                "sensor": pl.String,
                "detect": pl.Boolean,
                "inflation": pl.Float64,
                "negative": pl.Boolean,
            }
        )
    t0 = float(times[0])
    tk = pl.Series("tk", times)
    return (
        crossings.with_columns(stage=_stage_index(pl.col("t"), t0, period))
        .filter(pl.col("stage") < len(times))
        .group_by("stage", pl.col("beam").alias("sensor"))
        .agg(tc=pl.col("t").max())
        .with_columns(
            inflation=speed * (pl.lit(tk).gather(pl.col("stage")) - pl.col("tc") + hold),
            detect=pl.lit(True),
            negative=pl.lit(False),
        )
        .select("stage", "sensor", "detect", "inflation", "negative")
    )


# --------------------------------------------------------------------------- the stage


def run(inputs: dict, site: Site, config: IStateConfig) -> dict[str, pl.DataFrame]:
    """Run the I-state filter over the run's binary sensor tables.

    Inputs (all optional, ``TrackerSpec.wants``): ``motion`` (MOTION), ``proximity``
    (PROXIMITY), ``crossings`` (CROSSINGS). Outputs: ``tracks`` (TRACKS; a point summary:
    the centroids of the regions of the element of smallest total area, identities kept
    from stage to stage by ``linear_sum_assignment`` on centroid distance), ``summary``
    (t, stage, elements, area of the union of all regions within the free space, detections,
    rejected = readings rejected as contradicting the I-state, area_share = area / free space), ``regions`` (every
    region as WKB, for scoring and replay) and ``detections``.
    """
    n = config.targets or (site.targets or 0)
    if n < 1:
        raise ConfigError("istate: the number of targets is unknown; set 'targets' in site.toml or [istate] targets")
    sr = sensing_regions(site, config)
    index = {s: i for i, s in enumerate(sr.ids)}
    tables, cross = _binary_tables(inputs, index)
    times = stage_times(tables + ([cross] if cross is not None else []), config.period_s)
    rd, latency = _readings(inputs, tables, cross, times, index, config)
    # the filter runs in the site's normalised frame, its inputs snapped (unit-free, SiteFrame)
    frame = SiteFrame.of(site.free_space)
    steps, det = _stages(rd, sr, frame, site, times, n, latency, config)
    det_stage, det_bounds = det["stage"].to_numpy(), steps.det_bounds
    stage_state, state_rows, summ, track_xy = _filter(steps, config)
    summ[:, 3] *= frame.scale**2  # area in site units
    summary = pl.DataFrame(
        {
            "t": np.asarray(times, dtype=float),
            "stage": np.arange(len(times), dtype=np.int64),
            "elements": summ[:, 0].astype(np.int64),
            "area": summ[:, 3],
            "detections": np.diff(det_bounds).astype(np.int64),
            "rejected": summ[:, 1].astype(np.int64),
            "area_share": summ[:, 2],
        },
        schema=SUMMARY,
    )
    row_geoms: list = []
    regions = _regions_table(times, state_rows, n, frame, stage_state, row_geoms=row_geoms)
    track_xy = frame.xy_to_site(track_xy)
    K = len(times)
    tracks = conform(
        pl.DataFrame(
            {
                "tracker": [NAME] * (K * n),
                "track": np.tile([f"target{i + 1}" for i in range(n)], K).tolist(),
                "t": np.repeat(times, n),
                "x": track_xy[:, :, 0].ravel(),
                "y": track_xy[:, :, 1].ravel(),
            }
        ),
        TRACKS,
    ).with_columns(pl.col("x").fill_nan(None), pl.col("y").fill_nan(None))
    silent = silent_stretches([*tables, *([cross] if cross is not None else [])], min_s=config.absent_after)
    tracks = outside_silence(tracks, silent)  # the empty room: no point summary where nobody is
    detections = pl.DataFrame(
        {
            "t": times[det_stage] if len(times) else [],
            "stage": det_stage,
            "sensor": det["sensor"],
            "inflation": det["inflation"],
        },
        schema=DETECTIONS,
    )
    artifacts = {
        "sensing": dict(zip(sr.ids, sr.positive)),
        # the regions table's geometries, row by row (shared objects): its recording parses no WKB
        "region_geometries": np.concatenate(row_geoms) if row_geoms else np.zeros(0, dtype=object),
    }
    return {"tracks": tracks, "summary": summary, "regions": regions, "detections": detections, ARTIFACTS: artifacts}


def _binary_tables(inputs: dict, index: dict) -> tuple[list[pl.DataFrame], pl.DataFrame | None]:
    """``(tables, crossings)``: the motion and proximity tables present and the crossings (or
    None), checked and kept to the sensors the filter knows (``index``)."""
    tables = []
    for name, schema in (("motion", MOTION), ("proximity", PROXIMITY)):
        if name in inputs:
            df = check_schema(inputs[name], schema, name=name).filter(pl.col("sensor").is_in(list(index)))
            tables.append(df)
    cross = None
    if "crossings" in inputs:
        cross = check_schema(inputs["crossings"], CROSSINGS, name="crossings").filter(pl.col("beam").is_in(list(index)))
    return tables, cross


def _readings(
    inputs: dict, tables: list, cross, times, index: dict, config: IStateConfig
) -> tuple[pl.DataFrame, float]:
    """``(readings, latency)``: the rows the filter reads, per stage and sensor (sorted by stage
    and sensor index ``idx``), and the latency the levels' readings were built with."""
    T = config.period_s
    v = config.max_speed
    levels = pl.concat([df.select("t", "sensor", "on") for df in tables]) if tables else None
    latency = config.latency_s
    if config.latency_auto and levels is not None:
        latency = max(latency, time_resolution(levels["t"]))
    used = pl.col("detect") | (pl.col("negative") & pl.lit(config.reliable_negatives))  # the rows the filter reads
    readings = [state_readings(levels, times, T, latency, v).filter(used)] if tables else []
    if cross is not None:  # a crossing's stamp lags the body by up to the raw beam log's sampling interval
        events = inputs.get("beam_events")
        stamps = events["t"] if events is not None and events.height else cross["t"]
        lag = max(config.latency_s, time_resolution(stamps)) if config.latency_auto else config.latency_s
        readings.append(crossing_readings(cross, times, T, v, lag))
    rd = (
        pl.concat(readings)
        if readings
        else pl.DataFrame(
            schema={
                "stage": pl.Int64,
                "sensor": pl.String,
                "detect": pl.Boolean,
                "inflation": pl.Float64,
                "negative": pl.Boolean,
            }
        )
    )
    rd = rd.with_columns(idx=pl.col("sensor").replace_strict(index, return_dtype=pl.Int64)).sort("stage", "idx")
    return rd, latency


def _stages(rd: pl.DataFrame, sr, frame: SiteFrame, site: Site, times, n: int, latency: float, config: IStateConfig):
    """``(stages, detections)``: the filter's input in the frame (:class:`Stages`: each stage's
    detection regions, grown by their inflation and clipped to the free space, and its cleared
    regions) and the detection readings."""
    v = config.max_speed
    free = frame.outer(site.free_space)
    det = rd.filter("detect")
    pos = frame.outer(sr.positive)
    det_geom = (  # each distinct (sensor, inflation) grown and clipped once, shared by its readings
        _per_distinct(
            lambda i, d: shapely.intersection(grow(pos[i], d), free),
            det["idx"].to_numpy(),
            frame.length(det["inflation"].to_numpy()),
        )
        if det.height
        else np.zeros(0, object)
    )
    det_stage = det["stage"].to_numpy()
    neg = rd.filter(pl.col("negative") & pl.lit(config.reliable_negatives)) if config.reliable_negatives else rd.clear()
    # a reading may lag the target by latency_s: only S eroded by v latency_s is surely empty
    cleared = frame.inner(sr.negative)
    neg_geom = (
        _per_distinct(
            lambda i, d: shrink(cleared[i], d), neg["idx"].to_numpy(), np.full(neg.height, frame.length(v * latency))
        )
        if neg.height
        else np.zeros(0, object)
    )
    neg_stage = neg["stage"].to_numpy()
    keep_neg = ~shapely.is_empty(neg_geom) if len(neg_geom) else np.zeros(0, bool)
    neg_geom, neg_stage = neg_geom[keep_neg], neg_stage[keep_neg]
    steps = Stages(
        times=times,
        detections=det_geom,
        det_bounds=np.searchsorted(det_stage, np.arange(len(times) + 1)),
        negatives=neg_geom,
        neg_bounds=np.searchsorted(neg_stage, np.arange(len(times) + 1)),
        free=free,
        n=n,
        step=float(frame.length(v * config.period_s)),
    )
    return steps, det


def _per_distinct(make, idx: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """``make(idx, dist)`` (an elementwise geometry function of a sensor index and a length)
    computed once per distinct ``(idx, dist)`` pair, the result object shared by the rows with
    that pair (the same values as computing every row: each row's result depends on its pair only)."""
    idx = np.asarray(idx, dtype=np.int64)
    d, d_code = np.unique(np.asarray(dist, dtype=np.float64), return_inverse=True)
    _, first, inv = np.unique(idx * len(d) + d_code.reshape(-1), return_index=True, return_inverse=True)
    out = np.asarray(make(idx[first], d[d_code.reshape(-1)[first]]), dtype=object)
    return out[inv.reshape(-1)]


# --------------------------------------------------------------------------- the stage loop


#: Stages of the ``regions`` table built at once (:func:`_regions_table`).
REGIONS_CHUNK = 1 << 16

#: Entries (I-states, stage transitions, point summaries) :class:`_Transitions` keeps before
#: it starts afresh.
TRANSITIONS_CAPACITY = 1 << 16


@dataclass(frozen=True, kw_only=True)
class Stages:
    """The filter's inputs in the site's frame: the stage times, the sensing regions reading 1
    (``detections``, those of stage ``k`` at ``det_bounds[k]:det_bounds[k + 1]``) and the regions
    a reading 0 clears (``negatives``, likewise), the free space, ``n`` and the motion step
    ``s_tgt = v T``."""

    times: np.ndarray
    detections: np.ndarray
    det_bounds: np.ndarray
    negatives: np.ndarray
    neg_bounds: np.ndarray
    free: object
    n: int
    step: float


def _filter(stages: Stages, config: IStateConfig) -> tuple[np.ndarray, list, np.ndarray, np.ndarray]:
    """The filter over every stage: ``(I-state of each stage (K,), the regions of each of those
    I-states flattened, (K, 4) [elements, rejected, area / free area, area (frame units)],
    (K, n, 2) point summaries)``.

    Each stage is a function of the I-state it starts from, whether it moves (every stage but
    the first) and its readings' regions -- ``eta_k = f(eta_{k-1}, S_k)`` -- and its point
    summary a function of ``eta_k`` and the summary before. :class:`_Transitions` numbers the
    distinct I-states (by their regions' WKB) and the distinct reading regions, and looks a
    stage up when its ``(eta_{k-1}, moves, S_k)`` was met before: a room where nothing is read
    keeps an I-state that is a fixed point of the motion update (``F(eta) = eta``: the free
    space, or regions at walls), and a log whose readings recur (a beam crossed again and
    again) goes through the same I-states. A looked-up stage is the one computed (the same
    GEOS operations on the same coordinates give the same bits), so the result is
    :func:`onebit._testing.oracles.istate_filter_reference`'s, which computes every stage (the test oracle)."""
    times, n = stages.times, stages.n
    K = len(times)
    memo = PairMemo()  # region-pair results of the whole run (regions recur across stages)
    state_rows: list = []  # the regions of each distinct I-state of the run, flattened
    cache = _Transitions(state_rows)
    det_ids = cache.reading_ids(stages.detections)
    neg_ids = cache.reading_ids(stages.negatives)
    db, nb = stages.det_bounds.tolist(), stages.neg_bounds.tolist()
    free_area = float(stages.free.area) or 1.0
    cap = config.max_elements or None
    reject = config.contradictions == "reject"
    stage_state = np.zeros(K, dtype=np.int64)
    summ = np.zeros((K, 4))
    track_xy = np.zeros((K, n, 2))
    eta = IState.initial(stages.free, n)
    state = cache.state(eta)
    prev, prev_key = None, None
    for k in range(K):  # inherently sequential: the I-state of stage k depends on k-1
        if cache.full():  # start afresh (memory stays bounded): the state numbers are new
            cache.__init__(state_rows)
            state = cache.state(eta)
        d0, d1, g0, g1 = db[k], db[k + 1], nb[k], nb[k + 1]
        key = (state, k > 0, det_ids[d0:d1].tobytes() if d1 > d0 else b"", neg_ids[g0:g1].tobytes() if g1 > g0 else b"")
        hit = cache.step.get(key)
        if hit is None:
            rejected: list | None = [] if reject else None
            new = info_state_update(
                eta,
                stages.detections[d0:d1],
                step=stages.step if k else 0.0,
                free_space=stages.free,
                shape=config.shape,
                max_elements=cap,
                negatives=stages.negatives[g0:g1],
                substeps=config.substeps,
                memo=memo,
                rejected=rejected,
            )
            s = cache.state(new)
            area = cache.area(s, stages.free)  # once per distinct I-state
            hit = cache.step[key] = (s, (new.size, len(rejected or ()), area / free_area, area))
        state, summ[k] = hit
        eta = cache.etas[state]  # the I-state of this number met first: the same regions
        stage_state[k] = cache.run_number[state]
        pkey = (state, prev_key)
        xy = cache.summary.get(pkey)
        if xy is None:
            xy = cache.summary[pkey] = _point_summary(eta, prev, n)
            xy.flags.writeable = False
        track_xy[k] = prev = xy
        prev_key = xy.tobytes()
    return stage_state, state_rows, summ, track_xy


class _Transitions:
    """The distinct I-states of a run (numbered by their regions' WKB, with their flattened
    regions and total area), the stage transitions met (``(state, moves, reading ids, negative
    ids) -> (state, summary row)``) and the point summaries (``(state, previous summary) ->
    summary``) of :func:`_filter`; :meth:`full` past :data:`TRANSITIONS_CAPACITY` entries."""

    def __init__(self, run_rows: list) -> None:
        self.etas: list[IState] = []  # state number -> I-state
        self.run_rows = run_rows  # the regions of every I-state numbered in the run, flattened (kept on a reset)
        self.run_number: list[int] = []  # state number -> its index in run_rows
        self._area: dict[int, float] = {}  # state number -> area of the union of its regions
        self._number: dict[tuple, int] = {}  # (shape, region ids) -> state number
        self._rid: dict[bytes, int] = {}  # region WKB -> region id
        self._obj: dict[int, tuple[object, int]] = {}  # id(region) -> (region kept alive, region id)
        self.step: dict[tuple, tuple] = {}
        self.summary: dict[tuple, np.ndarray] = {}

    def full(self) -> bool:
        return len(self.step) + len(self.summary) + len(self.etas) + len(self._obj) > TRANSITIONS_CAPACITY

    @staticmethod
    def reading_ids(geoms: np.ndarray) -> np.ndarray:
        """One int32 per reading region, equal for equal WKB (each geometry object encoded once)."""
        if len(geoms) == 0:
            return np.zeros(0, dtype=np.int32)
        _, first, objs = np.unique(
            np.fromiter(map(id, geoms), dtype=np.int64, count=len(geoms)), return_index=True, return_inverse=True
        )
        _, inv = np.unique(shapely.to_wkb(geoms[first]), return_inverse=True)
        return inv.reshape(-1).astype(np.int32)[objs.reshape(-1)]

    def state(self, eta: IState) -> int:
        """The number of an I-state (a new one for an I-state not met before)."""
        ids = []
        for g in eta.regions.ravel().tolist():
            hit = self._obj.get(id(g))
            if hit is None:
                hit = self._obj[id(g)] = (g, self._rid.setdefault(shapely.to_wkb(g), len(self._rid)))
            ids.append(hit[1])
        key = (eta.regions.shape, tuple(ids))
        s = self._number.get(key)
        if s is None:
            s = self._number[key] = len(self.etas)
            self.etas.append(eta)
            self.run_number.append(len(self.run_rows))
            self.run_rows.append(eta.regions.ravel())
        return s

    def area(self, state: int, free) -> float:
        """:meth:`IState.total_area` of a state within the free space, computed once."""
        a = self._area.get(state)
        if a is None:
            a = self._area[state] = float(IState.total_area(self.etas[state], free))
        return a


def _regions_table(
    times: np.ndarray,
    regions: list,
    n: int,
    frame: SiteFrame,
    stage_state: np.ndarray | None = None,
    *,
    row_geoms: list | None = None,
) -> pl.DataFrame:
    """The ``regions`` table (REGIONS): stage ``k`` holds the flattened ``(E n,)`` region array
    ``regions[stage_state[k]]`` (in ``frame``; ``stage_state`` default ``0..K-1``, an array per
    stage); one row per region in site units, built once for the run (a region recurring
    across stages is mapped back, measured and encoded once: its WKB bytes are shared by its
    rows; an I-state recurring across stages is laid out once and its rows gathered).
    ``row_geoms`` (a list) receives the rows' geometries in site units (object arrays, one per
    chunk of rows), for the recording: the same objects, not parsed again from the WKB."""
    K = len(times)
    state = np.arange(K, dtype=np.int64) if stage_state is None else np.asarray(stage_state, dtype=np.int64)
    if K == 0 or not regions:
        return pl.DataFrame(schema=REGIONS)
    sizes_s = np.fromiter(map(len, regions), dtype=np.int64, count=len(regions))  # E n of each I-state
    flat = np.concatenate(regions) if sizes_s.sum() else np.zeros(0, dtype=object)
    _, first, inv = np.unique(
        np.fromiter(map(id, flat), dtype=np.int64, count=len(flat)), return_index=True, return_inverse=True
    )
    distinct = np.asarray(frame.to_site(flat[first]), dtype=object)
    area = shapely.area(distinct).astype(float)
    wkb = wkb_column(distinct)  # each region's WKB once, shared by the stages holding it
    if row_geoms is not None:  # one object per distinct WKB, as parsing the column gives
        _, one, same = np.unique(wkb.to_numpy(), return_index=True, return_inverse=True)
        canonical = distinct[one][same.reshape(-1)]
    code_of = inv.reshape(-1).astype(np.int64)  # distinct region of each position in ``flat``
    start_s = np.cumsum(sizes_s) - sizes_s
    times = np.asarray(times, dtype=float)
    parts = []
    for lo in range(0, K, REGIONS_CHUNK):  # stages in chunks: the temporaries stay O(chunk)
        st = state[lo : lo + REGIONS_CHUNK]
        sizes = sizes_s[st]  # rows of each stage
        total = int(sizes.sum())
        before = np.cumsum(sizes) - sizes  # first row of each stage
        within = np.arange(total, dtype=np.int64) - np.repeat(before, sizes)  # position in its stage
        code = code_of[np.repeat(start_s[st], sizes) + within]  # its I-state's region there
        parts.append(
            pl.DataFrame(
                {
                    "t": np.repeat(times[lo : lo + REGIONS_CHUNK], sizes),
                    "stage": np.repeat(np.arange(lo, lo + len(st), dtype=np.int64), sizes),
                    "element": within // n,
                    "k": within % n,
                    "area": area[code],
                    "wkb": wkb.gather(code),
                },
                schema=REGIONS,
            )
        )
        if row_geoms is not None:
            row_geoms.append(canonical[code])
    return pl.concat(parts, rechunk=False) if len(parts) > 1 else parts[0]


def _point_summary(eta: IState, prev: np.ndarray | None, n: int) -> np.ndarray:
    """``(n, 2)`` centroids of the regions of the smallest element, ordered to follow ``prev``."""
    if eta.size == 0:
        return np.full((n, 2), np.nan)
    best = int(np.argmin(shapely.area(eta.regions).sum(axis=1)))
    xy = shapely.get_coordinates(shapely.centroid(eta.regions[best]))
    if prev is None or np.isnan(prev).any() or len(xy) != n:
        return xy if len(xy) == n else np.full((n, 2), np.nan)
    cost = np.hypot(*(prev[:, None, :] - xy[None, :, :]).transpose(2, 0, 1))
    r, c = _optimize.linear_sum_assignment(cost)
    return xy[c[np.argsort(r)]]


SPEC = TrackerSpec(
    name=NAME,
    needs=(),
    counts_people=True,
    wants=("motion", "proximity", "crossings", "beam_events"),
    config=IStateConfig,
    run=run,
    available=available,
    fits=fits,
    help="O'Kane set-based I-state filter over binary sensors (union of products)",
)
