"""``onebit check DATASET``: which trackers can run on a dataset, what each lacks, and which
sensors look like they are not about people.

For every tracker of :data:`onebit.pipeline.stages.TRACKERS`: the tables it needs against the
logs in the folder (its ``needs``, made by the reader stages from ``motion.csv``,
``frames.csv``, ...), then its own ``available(site)`` on the site as the trackers see it
(:attr:`onebit.core.site.Site.tracked`). For the dataset: what is missing for scoring or for
some trackers (sensor positions still placeholders of ``onebit init``, a sensor graph,
``targets``, truth).

Sensors that look like non-person sensors (:func:`suspect_sensors`), from the readers' own
tables of rising edges (an ``on``):

* **flicker in empty periods** -- at least ``min_ons`` of a sensor's ons, and at least
  ``solo_share`` of them, fall in stretches where no other sensor turned on within
  ``quiet_s`` before and after (a house with nobody moving: a temperature sensor toggling);
* **never co-firing with neighbours** -- of at least ``min_ons`` ons, the share with an on of
  a neighbour (sensor-graph neighbours, else the ``neighbours`` nearest sensors, else every
  other) within ``window_s`` is no more than ``lift`` times what independent sensors would
  give (``1 - exp(-2 window_s rate)``, ``rate`` the neighbours' ons per second).

Both are hints: a person alone in a room for an hour also fires one sensor alone. The report
names the numbers so the user can judge, and says how to leave a sensor out (``ignore = true``).

Sensors **out of place on the plan** (:func:`onebit.models.occupancy.out_of_place`, eq. F1 of
the home's count model): where the count weighs far pairs (a floor plan's ``run.toml``, ``walk_s
= 0``, or a site without a sensor graph), a sensor whose share of the far pairs' ends is
``far_lift`` times its share of the firings -- moved since the plan was drawn, or seeing into the
next room. The count model already leaves their far pairs out; the check names them so the
plan can be corrected.
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.config import config_from_mapping
from onebit.core.errors import InputError
from onebit.core.params import param, validate
from onebit.core.region_graph import build_region_graph
from onebit.core.site import Site, load_site
from onebit.core.units import config_in_site_units
from onebit.models.occupancy import OccupancyConfig, out_of_place
from onebit.pipeline.context import RunContext
from onebit.pipeline.stages import TRACKERS, stages

#: The reader stages whose tables ``check`` reads (the runner's own).
READERS = ("crossings", "truth", "truth_events", "frames", "motion", "proximity")
#: Which log makes each table a tracker may need.
MADE_BY = {
    "motion": "motion.csv or frames.csv",
    "proximity": "proximity.csv or frames.csv",
    "proximity_frames": "proximity.csv or frames.csv (with proximity or binary sensors)",
    "crossings": "beams.csv or crossings.csv",
    "levels": "frames.csv",
}
#: The mark ``onebit init`` leaves on a placeholder position.
PLACEHOLDER = "# CHECK: placeholder position"


@dataclass(frozen=True)
class SuspectConfig:
    """How :func:`suspect_sensors` judges a sensor (module docstring)."""

    quiet_s: float = param(
        600.0, "no other sensor on within this long before and after: an empty stretch", lo=0.0, unit="s"
    )
    solo_share: float = param(0.5, "share of a sensor's ons in empty stretches that flags it", lo=0.0, hi=1.0)
    min_ons: int = param(20, "fewer ons than this: too few to judge", lo=0)
    window_s: float = param(30.0, "an on of a neighbour within this long: co-firing", lo=0.0, unit="s")
    lift: float = param(1.5, "co-firing no more than this times chance flags a sensor", lo=0.0)
    neighbours: int = param(3, "nearest sensors taken as neighbours when the site has no graph", lo=0)

    def __post_init__(self) -> None:
        validate(self)


@dataclass
class CheckResult:
    """What :func:`check_dataset` found."""

    site: Site
    logs: list[str]
    runs: dict[str, str] = field(default_factory=dict)  #: tracker -> "" (can run)
    cannot: dict[str, str] = field(default_factory=dict)  #: tracker -> why not
    missing: list[str] = field(default_factory=list)  #: what the dataset lacks, in words
    suspects: pl.DataFrame | None = None  #: sensor, reason, ons, numbers
    out_of_place: pl.DataFrame | None = None  #: sensor, ons, far_ends, lift (eq. F1)
    problems: list[str] = field(default_factory=list)  #: readers that failed, in words


def check_dataset(dataset: str | Path, config: SuspectConfig = SuspectConfig()) -> CheckResult:
    """Check a dataset folder (module docstring)."""
    dataset = Path(dataset)
    site_path = dataset / "site.toml"
    if not site_path.is_file():
        raise InputError("no site.toml; 'onebit init DATASET --from LOG' writes a skeleton", file=str(dataset))
    site = load_site(site_path)
    logs = sorted(p.name for p in dataset.iterdir() if p.suffix in (".csv", ".mcap", ".mp4"))
    res = CheckResult(site, logs)
    ctx = _read(dataset, site, res)
    tables = ctx.tables
    tracked = site.tracked
    for entry in TRACKERS:
        spec = entry.spec
        lacking = [k for k in spec.needs if not any(s in tables for s in entry.inputs.get(k, (k,)))]
        if lacking:
            res.cannot[entry.name] = "needs " + "; ".join(f"'{k}' (from {MADE_BY.get(k, k)})" for k in lacking)
            continue
        if not spec.needs and spec.wants and not any(k in tables for k in spec.wants):
            res.cannot[entry.name] = "needs one of " + ", ".join(f"'{k}'" for k in spec.wants)
            continue
        reason = spec.available(tracked) if spec.available is not None else None
        if reason is not None:
            res.cannot[entry.name] = reason
        else:
            res.runs[entry.name] = ""
    text = site_path.read_text(encoding="utf-8", errors="replace")
    if PLACEHOLDER in text:
        res.missing.append(
            f"positions: {text.count(PLACEHOLDER)} sensors still at the placeholder positions of 'onebit init' "
            "(every tracker that places people uses them)"
        )
    if tracked.motion_sensors and (tracked.sensor_graph is None or not tracked.sensor_graph.edges):
        res.missing.append(
            "graph: no [sensor_graph] with edges (findinghumo, hmm1, hmm2, findinghumo-flow need it; "
            'geometry = "connected" builds one from the positions)'
        )
    if site.targets is None:
        res.missing.append("targets: site.toml does not say how many people at most (istate and correct need it)")
    if "truth" not in tables and "truth_events" not in tables:
        res.missing.append("truth: no truth.csv or truth_events.csv, so the trackers run but are not scored")
    edges = [tables[k].filter(pl.col("on")) for k in ("motion", "proximity") if k in tables]
    ons = (
        pl.concat(edges).select("t", "sensor").unique()
        if edges
        else pl.DataFrame(schema={"t": pl.Float64, "sensor": pl.String})
    )
    res.suspects = suspect_sensors(ons, site, config)
    if "motion" in tables and tracked.motion_sensors:
        occ = config_from_mapping(OccupancyConfig, ctx.section("occupancy"), section="occupancy")
        res.out_of_place = out_of_place(tables["motion"], tracked, config_in_site_units(occ, site))
    return res


def _read(dataset: Path, site: Site, res: CheckResult) -> RunContext:
    """The reader stages' tables (in the returned context's ``tables``), made as a run makes
    them (its time origin, its rules)."""
    with tempfile.TemporaryDirectory(prefix="onebit-check-") as tmp:
        ctx = RunContext(dataset, Path(tmp), site, build_region_graph(site), {})
        for stage in stages():
            if stage.name not in READERS:
                continue
            try:
                if stage.available(ctx) is not None:
                    continue
                ctx.tables.update({k: v for k, v in stage.work(ctx).items() if isinstance(v, pl.DataFrame)})
            except InputError as exc:
                res.problems.append(f"{stage.name}: {exc}")
    return ctx


def _neighbours(site: Site, ids: list[str], k: int) -> dict[str, list[str]]:
    """Each sensor's neighbours: its sensor-graph neighbours, else its ``k`` nearest sensors."""
    g = site.sensor_graph
    if g is not None and g.edges:
        out: dict[str, list[str]] = {i: [] for i in ids}
        for a, b in g.edges:
            out.setdefault(a, []).append(b)
            out.setdefault(b, []).append(a)
        if all(out.get(i) for i in ids if i in g.nodes):
            return {i: out.get(i) or [j for j in ids if j != i] for i in ids}
    pos = {m.id: m.position for m in site.motion_sensors} | {p.id: p.position for p in site.proximity_sensors}
    out = {}
    for i in ids:
        others = [j for j in ids if j != i]
        if i in pos:
            others.sort(key=lambda j: math.dist(pos[i], pos[j]) if j in pos else math.inf)
            out[i] = others[:k]
        else:
            out[i] = others
    return out


def suspect_sensors(ons: pl.DataFrame, site: Site, config: SuspectConfig = SuspectConfig()) -> pl.DataFrame:
    """Sensors that look like non-person sensors (module docstring), from ``ons`` (``t``,
    ``sensor``: one row per rising edge). One row per flag: ``sensor``, ``reason``, ``ons``,
    ``solo_share`` (share of its ons in empty stretches), ``cofire`` (share with a neighbour's
    on within ``window_s``), ``chance`` (that share for independent sensors)."""
    schema = {
        "sensor": pl.String,
        "reason": pl.String,
        "ons": pl.Int64,
        "solo_share": pl.Float64,
        "cofire": pl.Float64,
        "chance": pl.Float64,
    }
    ids = sorted(ons["sensor"].unique().to_list()) if ons.height else []
    if len(ids) < 2:
        return pl.DataFrame(schema=schema)
    by = {s: np.sort(ons.filter(pl.col("sensor") == s)["t"].to_numpy()) for s in ids}
    span = float(ons["t"].max() - ons["t"].min()) or 1.0
    near = _neighbours(site, ids, config.neighbours)
    rows = []
    for s in ids:
        t = by[s]
        if t.size < config.min_ons:
            continue
        others = np.sort(np.concatenate([by[j] for j in ids if j != s]))
        gap_before, gap_after = _gaps(t, others)
        solo = float(np.mean((gap_before >= config.quiet_s) & (gap_after >= config.quiet_s)))
        nb = [j for j in near.get(s, []) if j in by]
        nt = np.sort(np.concatenate([by[j] for j in nb])) if nb else np.empty(0)
        b, a = _gaps(t, nt)
        cofire = float(np.mean(np.minimum(b, a) <= config.window_s))
        chance = 1.0 - math.exp(-2.0 * config.window_s * nt.size / span)
        base = (s, t.size, solo, cofire, chance)
        if solo >= config.solo_share:
            rows.append((base[0], "flicker in empty periods", *base[1:]))
        if cofire <= config.lift * chance:
            rows.append((base[0], "never co-fires with its neighbours", *base[1:]))
    return pl.DataFrame(rows, schema=schema, orient="row")


def _gaps(t: np.ndarray, others: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each time of ``t``: the time since the last of ``others`` before it and to the
    next after it (``inf`` when there is none)."""
    if others.size == 0:
        inf = np.full(t.shape, np.inf)
        return inf, inf
    i = np.searchsorted(others, t, side="left")
    before = np.where(i > 0, t - others[np.maximum(i - 1, 0)], np.inf)
    j = np.searchsorted(others, t, side="right")
    after = np.where(j < others.size, others[np.minimum(j, others.size - 1)] - t, np.inf)
    return before, after


def format_check(res: CheckResult) -> str:
    """The check as text, for the terminal."""
    out = [f"site {res.site.name!r}: logs {', '.join(res.logs) or 'none'}"]
    if res.site.ignored:
        out.append(f"ignored (ignore = true): {', '.join(sorted(res.site.ignored))}")
    out += [f"  problem: {p}" for p in res.problems]
    out.append(f"can run ({len(res.runs)}): {', '.join(res.runs) or 'none'}")
    out.append(f"cannot run ({len(res.cannot)}):")
    out += [f"  {name}: {why}" for name, why in res.cannot.items()]
    out.append("missing:" if res.missing else "missing: nothing")
    out += [f"  {m}" for m in res.missing]
    sus = res.suspects
    if sus is None or sus.height == 0:
        out.append("sensors that look like non-person sensors: none")
    else:
        out.append("sensors that look like non-person sensors (check them; 'ignore = true' leaves one out):")
        for s, reason, n, solo, co, ch in sus.iter_rows():
            out.append(
                f"  {s}: {reason} ({n} ons, {solo:.0%} with no other sensor on within the quiet time, "
                f"{co:.0%} with a neighbour's on nearby against {ch:.0%} by chance)"
            )
    odd = res.out_of_place
    if odd is not None and odd.height:
        out.append(
            "sensors out of place on the plan? (they pair far with other sensors out of proportion to their "
            "firings: moved, or seeing into the next room; a rare sensor can too. The count leaves their far "
            "pairs out; check their positions):"
        )
        for s, n, ends, lam in odd.iter_rows():
            out.append(f"  {s}: {ends} far-pair ends of {n} ons, {lam:.1f} times its share of the firings")
    return "\n".join(out)
