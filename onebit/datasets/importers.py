"""Importers: the field's own recordings -> onebit dataset folders.

``onebit import casas LOG DATASET_DIR [--layout layout.toml] [--targets N]``
    (:func:`import_casas`) -- a CASAS smart-home log (:mod:`onebit.readers.casas`) becomes::

        site.toml        motion sensors (M### and the D### doors), their sensor graph, epoch
        motion.csv       t, sensor, value (ON/OFF, OPEN/CLOSE as logged), stamp, log_line
        other.csv        every other sensor's events (temperature, lights, ...), nothing lost
        annotations.csv  the annotated lines (activity labels), with their sensor and value
        rejects.csv      the lines the reader rejected, with their reasons (when there are any)
        import.toml      what was done: counts, time origin, how the graph and positions were found

    ``t`` is seconds since ``site.toml``'s ``epoch``, the log's first second.

``onebit import trajectories FILE DATASET_DIR`` (:func:`import_trajectories`) -- a
people-counter or indoor-positioning export becomes ``truth.csv`` (see
:mod:`onebit.readers.trajectories`), and a ``site.toml`` holding the walks' bounding box
when the folder has none yet.

Sensor graph and positions of a CASAS home
-----------------------------------------
With a layout file (``--layout``), positions (and, if it gives them, the edges) come from it.
Without one the graph is **learned from the log** (:func:`learn_sensor_graph`): take the
``ON``/``OPEN`` events of the motion and door sensors in time order; each two consecutive ones
from different sensors, ``dt <= window_s`` (5 s) apart, are one *transition* between them
(either direction). Sensors ``a`` and ``b`` are adjacent when they have at least
``min_count`` (3) transitions and those are at least ``min_share`` (10 %) of the transitions
of the less busy of the two, and their *lift* (their count over the count chance would give
if the two sensors' transitions were independent) is at least ``min_lift`` (2) -- a person
walking trips neighbouring sensors one after the other far more often than chance, while a
skipped sensor (a missed detection) makes rarer pairs and two people moving at once in two
rooms interleave their events about as chance would (lift ~ 1): they do not link the rooms. Components left apart are joined by the edges of a maximum spanning forest of
the transition counts (the most frequent transitions between them). Nodes get positions from
a force layout of that graph (``networkx.spring_layout``, seeded; edge length ``spacing_m``,
3 m) -- **not measured**: ``import.toml`` says ``positions = "force layout"`` and
``site.toml`` says so in its header. Door sensors (``D###``) are the graph's entry and exit
nodes, with an entry signature ``door -> neighbour`` for each neighbour (FindingHuMo's
``Sig_in``; the reverse is an exit). Layout files and floor plans are read by
:mod:`onebit.datasets.layouts`.
"""

from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.errors import InputError
from onebit.core.lazy import lazy_module
from onebit.core.site import load_site, site_from_dict
from onebit.core.tables import REJECTS
from onebit.core.writers import to_toml, write_csv, write_text
from onebit.datasets.layouts import Layout, load_floor_plan, load_layout, match_ids
from onebit.readers.casas import (
    DEFAULT_HOLD_S,
    MIN_HOLD_SAMPLES,
    TOGGLE_KINDS,
    CasasLog,
    read_casas,
    repair_lost_offs,
)
from onebit.readers.trajectories import TrajectoryFormat, read_trajectories

nx = lazy_module("networkx")

#: Defaults of the learned-graph rule (module docstring).
WINDOW_S = 5.0
MIN_COUNT = 3
MIN_SHARE = 0.1
MIN_LIFT = 2.0
SPACING_M = 3.0


@dataclass
class ImportSummary:
    """What an import wrote (also in ``import.toml``)."""

    dataset: Path
    counts: dict[str, int] = field(default_factory=dict)
    info: dict = field(default_factory=dict)


# --------------------------------------------------------------------------- the graph


def transitions(events: pl.DataFrame, *, window_s: float = WINDOW_S) -> pl.DataFrame:
    """Transition counts ``(a, b, n)`` (``a < b``) between consecutive ON events of different
    sensors at most ``window_s`` apart (``events``: t, sensor, on; sorted by t)."""
    on = events.filter(pl.col("on")).select("t", "sensor").sort("t", maintain_order=True)
    pairs = on.with_columns(nxt=pl.col("sensor").shift(-1), dt=pl.col("t").shift(-1) - pl.col("t")).filter(
        pl.col("nxt").is_not_null() & (pl.col("nxt") != pl.col("sensor")) & (pl.col("dt") <= window_s)
    )
    a = pl.min_horizontal("sensor", "nxt")
    b = pl.max_horizontal("sensor", "nxt")
    return pairs.group_by(a.alias("a"), b.alias("b")).agg(n=pl.len().cast(pl.Int64)).sort("a", "b")


def learn_sensor_graph(
    events: pl.DataFrame,
    nodes: list[str],
    *,
    window_s: float = WINDOW_S,
    min_count: int = MIN_COUNT,
    min_share: float = MIN_SHARE,
    min_lift: float = MIN_LIFT,
) -> tuple[list[tuple[str, str]], pl.DataFrame]:
    """Edges of the sensor graph learned from ON events (module docstring), and the
    transition table with columns a, b, n, share, lift, kept (``"rule"``, ``"joins
    components"`` or null).

    ``lift = n / E``, ``E = n_a n_b / (2 T)``: the pair's transitions over what chance would
    give if the two sensors' transitions were independent (``n_a``: transitions touching
    ``a``, ``T``: all transitions). Two people moving at once in two rooms interleave their
    events about as chance would (lift ~ 1); a walker makes neighbours follow each other far
    more often than that, so an edge needs ``lift >= min_lift`` too."""
    tr = transitions(events, window_s=window_s)
    busy = (
        pl.concat([tr.select(pl.col("a").alias("s"), "n"), tr.select(pl.col("b").alias("s"), "n")])
        .group_by("s")
        .agg(total=pl.col("n").sum())
    )
    tr = (
        tr.join(busy.rename({"s": "a", "total": "ta"}), on="a")
        .join(busy.rename({"s": "b", "total": "tb"}), on="b")
        .with_columns(
            share=pl.col("n") / pl.min_horizontal("ta", "tb"),
            lift=pl.col("n") * 2.0 * pl.col("n").sum() / (pl.col("ta") * pl.col("tb")),
        )
        .with_columns(
            kept=pl.when(
                (pl.col("n") >= min_count) & (pl.col("share") >= min_share) & (pl.col("lift") >= min_lift)
            ).then(pl.lit("rule"))
        )
        .drop("ta", "tb")
        .sort("a", "b")
    )
    g = nx.Graph()
    g.add_nodes_from(nodes)
    g.add_edges_from(tr.filter(pl.col("kept").is_not_null()).select("a", "b").rows())
    counts = nx.Graph()
    counts.add_nodes_from(nodes)
    counts.add_weighted_edges_from(tr.select("a", "b", "n").rows())
    joins = set()
    for a, b in nx.maximum_spanning_edges(counts, data=False):  # the most frequent transitions first
        if not nx.has_path(g, a, b):
            g.add_edge(a, b)
            joins.add((min(a, b), max(a, b)))
    if joins:
        j = pl.DataFrame(sorted(joins), schema={"a": pl.String, "b": pl.String}, orient="row").with_columns(
            _join=pl.lit(True)
        )
        tr = (
            tr.join(j, on=["a", "b"], how="left")
            .with_columns(kept=pl.when(pl.col("_join")).then(pl.lit("joins components")).otherwise(pl.col("kept")))
            .drop("_join")
        )
    edges = sorted((min(a, b), max(a, b)) for a, b in g.edges())
    return edges, tr


def force_layout(
    nodes: list[str], edges: list[tuple[str, str]], *, spacing: float = SPACING_M, seed: int = 0
) -> dict[str, tuple[float, float]]:
    """Positions from a seeded force layout, scaled so the median edge is ``spacing`` long and
    moved so every position is at least ``spacing`` from the axes."""
    g = nx.Graph()
    g.add_nodes_from(nodes)
    g.add_edges_from(edges)
    if len(nodes) == 1:
        return {nodes[0]: (spacing, spacing)}
    pos = nx.spring_layout(g, seed=seed, iterations=300)
    xy = np.array([pos[n] for n in nodes], dtype=float)
    if edges:
        idx = {n: i for i, n in enumerate(nodes)}
        lengths = np.array([np.hypot(*(xy[idx[a]] - xy[idx[b]])) for a, b in edges])
        med = float(np.median(lengths[lengths > 0])) if np.any(lengths > 0) else 1.0
    else:
        med = float(np.median(np.hypot(*(xy - xy.mean(axis=0)).T))) or 1.0
    xy = xy / med * spacing
    xy = xy - xy.min(axis=0) + spacing
    return {n: (round(float(x), 3), round(float(y), 3)) for n, (x, y) in zip(nodes, xy)}


# --------------------------------------------------------------------------- site.toml


def _v(x) -> str:
    if isinstance(x, bool):
        return "true" if x else "false"
    if isinstance(x, (int, float)):
        return repr(round(float(x), 6)) if isinstance(x, float) else str(x)
    if isinstance(x, (list, tuple)):
        return "[" + ", ".join(_v(y) for y in x) + "]"
    return '"' + str(x).replace("\\", "\\\\").replace('"', '\\"') + '"'


def graph_site_toml(
    *,
    name: str,
    units: str,
    positions: dict[str, tuple[float, float]],
    edges: list[tuple[str, str]],
    doors: list[str],
    sensor_range: float,
    boundary: list | None = None,
    epoch: str | None = None,
    targets: int | None = None,
    header: str = "",
) -> str:
    """``site.toml`` of a sensor-graph home: motion sensors (doors included) with a detection
    disk of ``sensor_range``, the graph, doors as entries/exits with ``door -> neighbour``
    signatures, the boundary (else the positions' box grown by twice the range)."""
    xy = np.array(list(positions.values()), dtype=float)
    if boundary is None:
        m = 2.0 * sensor_range
        (x0, y0), (x1, y1) = xy.min(axis=0) - m, xy.max(axis=0) + m
        boundary = [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]
    g = nx.Graph(edges)
    sigs = [[d, n] for d in doors if d in g for n in sorted(g.neighbors(d)) if n not in doors]
    lines = [header.rstrip("\n")] if header else []
    lines += [f"name = {_v(name)}", f"units = {_v(units)}"]
    if epoch is not None:
        lines.append(f"epoch = {_v(epoch)}")
    if targets is not None:
        lines.append(f"targets = {int(targets)}")
    lines += ["", "[boundary]", f"polygon = {_v([[float(a), float(b)] for a, b in boundary])}", ""]
    for sid, (x, y) in positions.items():
        lines += [
            "[[motion_sensors]]",
            f"id = {_v(sid)}",
            f"position = {_v([x, y])}",
            f"range = {_v(float(sensor_range))}",
            "",
        ]
    lines += [
        "[sensor_graph]",
        f"edges = {_v([list(e) for e in edges])}",
        f"entries = {_v(doors)}",
        f"exits = {_v(doors)}",
        f"signatures = {_v(sigs)}",
        "",
    ]
    return "\n".join(lines)


# --------------------------------------------------------------------------- CASAS


def _casas_layout(layout, log: Path, *, scale, rooms, graph_radius) -> Layout | None:
    """The layout file or floor plan (None without one), its ids renamed to the log's."""
    lay = None
    if layout is not None:
        lay = (
            load_layout(layout)
            if Path(layout).suffix.lower() == ".toml"
            else load_floor_plan(layout, scale=scale, rooms=rooms, radius=graph_radius)
        )
        lay = _renamed(lay, read_casas(log).events["sensor"].unique().to_list())
    return lay


def _casas_site_toml(log: Path, res: CasasLog, lay: Layout | None, g, door_ids: list, targets: int | None) -> str:
    """The text of the imported home's ``site.toml``, its header saying where the positions
    and the graph come from."""
    epoch = _epoch_text(res)
    header = (
        f"# Imported from the CASAS log {log.name} by 'onebit import casas' (see import.toml).\n"
        + (
            "# Sensor positions: a force layout of the sensor graph learned from the log -- NOT measured.\n"
            if g.how == "force layout"
            else f"# Sensor positions from the layout file {Path(lay.source).name}.\n"
        )
        + f"# Sensor graph: {g.graph_how}; entry/exit nodes: the doors a layout or --doors declares ({len(door_ids)}), "
        "never cupboard or appliance contacts.\n"
    )
    text = graph_site_toml(
        name=(lay.name if lay is not None and lay.name else log.stem),
        units=g.units,
        positions=g.positions,
        edges=g.edges,
        doors=door_ids,
        sensor_range=g.sensor_range,
        boundary=lay.boundary if lay is not None else None,
        epoch=epoch,
        targets=targets if targets is not None else (lay.targets if lay is not None else None),
        header=header,
    )
    return text


def import_casas(
    log: str | Path,
    dataset: str | Path,
    *,
    layout: str | Path | None = None,
    targets: int | None = None,
    doors: tuple[str, ...] | list[str] = (),
    window_s: float = WINDOW_S,
    min_count: int = MIN_COUNT,
    min_share: float = MIN_SHARE,
    spacing_m: float = SPACING_M,
    hold_s: float = DEFAULT_HOLD_S,
    hold_samples: int = MIN_HOLD_SAMPLES,
    scale: float | None = None,
    rooms: str | Path | None = None,
    graph_radius: float | None = None,
    count: int | None = None,
) -> ImportSummary:
    """Write a dataset folder from a CASAS log (module docstring); every file atomically.

    ``count``: the number of people in throughout, when it is known and constant (a
    one-resident session): written as ``truth_count.csv`` over the log's span, so the run
    scores every people count per minute against it (docs/homes.md).

    ``doors``: contact sensors that are doors to the outside (entry/exit nodes), beside the
    layout's; every other contact (cupboards, appliances) is an ordinary node. ``hold_s`` /
    ``hold_samples``: the lost-OFF repair (:func:`onebit.readers.casas.repair_lost_offs`).

    Steps: the arguments checked, the layout read (if any), the log read and split
    (:func:`_casas_parts`), the sensor graph and positions found (:func:`_casas_graph`), the
    site written only if it loads, then the tables and ``import.toml`` (:func:`_casas_record`)."""
    log, out = Path(log), Path(dataset)
    if count is not None and count < 0:
        raise InputError(f"--count {count}: a number of people >= 0", field="count")
    _check_casas_args(
        log,
        targets=targets,
        window_s=window_s,
        spacing_m=spacing_m,
        min_share=min_share,
        hold_s=hold_s,
        hold_samples=hold_samples,
    )
    lay = _casas_layout(layout, log, scale=scale, rooms=rooms, graph_radius=graph_radius)
    kinds = dict(lay.kinds) if lay is not None else {}
    kinds.update({d: "door" for d in doors})
    res: CasasLog = read_casas(log, kinds=kinds or None)
    parts = _casas_parts(res, lay, log, doors=doors, hold_s=hold_s, hold_samples=hold_samples)
    g = _casas_graph(parts, lay, window_s=window_s, min_count=min_count, min_share=min_share, spacing_m=spacing_m)
    door_ids = [n for n in g.positions if n in parts.door_ids]
    text = _casas_site_toml(log, res, lay, g, door_ids, targets)
    site_from_dict(tomllib.loads(text), source=str(out / "site.toml"))  # refuse to write a site that would not load
    out.mkdir(parents=True, exist_ok=True)
    write_text(text, out / "site.toml")
    _write_casas_tables(out, parts, res, g.transitions)
    counts, info = _casas_record(
        log,
        res,
        parts,
        g,
        door_ids,
        window_s=window_s,
        min_count=min_count,
        min_share=min_share,
        hold_s=hold_s,
        hold_samples=hold_samples,
    )
    write_text(to_toml(info), out / "import.toml")
    if count is not None:
        write_csv(known_count(parts.toggles["t"], count), out / "truth_count.csv")
    if lay is not None and g.how != "force layout":
        write_text(PLAN_RUN_TOML, out / "run.toml")
    return ImportSummary(out, counts, info)


def known_count(t: pl.Series, count: int) -> pl.DataFrame:
    """``truth_count`` (t, end, count) of a count known and constant over the times ``t``:
    one interval from the first whole second to the second after the last.

    >>> known_count(pl.Series([3.2, 50.0, 99.5]), 1).rows()
    [(3.0, 100.0, 1)]
    """
    if t.len() == 0:
        return pl.DataFrame(schema={"t": pl.Float64, "end": pl.Float64, "count": pl.Int64})
    lo, hi = math.floor(float(t.min())), math.floor(float(t.max())) + 1.0
    return pl.DataFrame({"t": [float(lo)], "end": [float(hi)], "count": [int(count)]})


#: The dataset's own ``run.toml`` of a CASAS home imported with a floor plan: the home's count
#: model (stage ``occupancy``) judges "two sensors too far apart for one person" on the plan's
#: graph (docs/homes.md: chosen on one half of the development sessions with the Kyoto plan).
PLAN_RUN_TOML = """# Written by 'onebit import casas --layout': the positions are the floor plan's, so the home's
# count model calls two sensors 2 hops apart on the plan's graph, fired within 2 s, two people
# (without a plan the learned graph's hops are looser: the defaults, 4 hops within 1 s, and the
# strays of one walker instead of far pairs; walk_s = 0 turns that term off here).
[occupancy]
far_hops = 2
window_s = 2.0
far_noise = 0.1
walk_s = 0.0
"""


def _check_casas_args(log: Path, *, targets, window_s, spacing_m, min_share, hold_s, hold_samples) -> None:
    """The log exists and every option is in range (the error names the option)."""
    if not log.is_file():
        raise InputError("no such CASAS log", file=log)
    for name, v, lo in (
        ("--window", window_s, 0.0),
        ("--spacing", spacing_m, 0.0),
        ("--min-share", min_share, -1e-12),
        ("--hold", hold_s, 0.0),
    ):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > lo):
            raise InputError(f"{name} = {v!r}: must be a positive number")
    if targets is not None and targets < 0:
        raise InputError(f"--targets = {targets!r}: must be >= 0")
    if not isinstance(hold_samples, int) or hold_samples < 1:
        raise InputError(f"--hold-samples = {hold_samples!r}: must be an integer >= 1")


@dataclass(frozen=True)
class _CasasParts:
    """A CASAS log split into what the dataset folder holds (:func:`_casas_parts`)."""

    events: pl.DataFrame  #: every event read
    toggles: pl.DataFrame  #: the graph sensors' events, lost OFFs repaired (motion.csv)
    others: pl.DataFrame  #: every other event (other.csv)
    notes: pl.DataFrame  #: annotated lines (annotations.csv)
    truth_events: pl.DataFrame  #: ON/OPEN events with residents (truth_events.csv)
    repairs: pl.DataFrame  #: the OFFs added (lost_offs.csv)
    nodes: list[str]  #: the graph sensors that fired
    door_ids: list[str]  #: the doors among them
    unplaced: list[str]  #: graph sensors a layout does not place (kept in other.csv)


def _casas_parts(
    res: CasasLog, lay: Layout | None, log: Path, *, doors, hold_s: float, hold_samples: int
) -> _CasasParts:
    """Split the read log: graph sensors (motion, doors and named motion sensors the layout
    places) to ``motion.csv`` with lost OFFs repaired, the rest to ``other.csv``; refuse a log
    with no graph sensor and a ``--doors`` naming none."""
    ev = res.events
    unplaced: list[str] = []
    if lay is not None:  # graph sensors the layout does not place: kept in other.csv, named in import.toml
        graph_ids = ev.filter(pl.col("kind").is_in(list(TOGGLE_KINDS)))["sensor"].unique().to_list()
        unplaced = sorted((n for n in graph_ids if n not in lay.positions), key=_natural)
    in_graph = pl.col("kind").is_in(list(TOGGLE_KINDS)) & ~pl.col("sensor").is_in(unplaced)
    toggles_logged = ev.filter(in_graph)
    toggles, repairs = repair_lost_offs(toggles_logged, default_hold_s=hold_s, min_samples=hold_samples)
    nodes = sorted(toggles["sensor"].unique().to_list(), key=_natural)
    if not nodes:
        raise InputError(
            "no motion (M###), contact (D###) or named motion sensor events in the log: nothing to track", file=log
        )
    missing_doors = [d for d in doors if d not in nodes]
    if missing_doors:
        raise InputError(
            f"--doors {missing_doors}: no such contact sensor among the log's graph sensors {nodes}", file=log
        )
    return _CasasParts(
        events=ev,
        toggles=toggles,
        others=ev.filter(~in_graph),
        notes=ev.filter(pl.col("annotation").is_not_null() | pl.col("residents").is_not_null()),
        truth_events=toggles_logged.filter(pl.col("on") & pl.col("residents").is_not_null()),
        repairs=repairs,
        nodes=nodes,
        door_ids=sorted(toggles.filter(pl.col("kind") == "door")["sensor"].unique().to_list(), key=_natural),
        unplaced=unplaced,
    )


@dataclass(frozen=True)
class _CasasGraph:
    """The sensor graph and positions of an imported home (:func:`_casas_graph`)."""

    positions: dict[str, tuple[float, float]]
    edges: list
    units: str
    how: str  #: where the positions come from: "layout file" or "force layout"
    graph_how: str  #: where the edges come from: "layout file", "geometry" or "learned"
    rule: str  #: how the edges were found, in words (import.toml)
    spacing: float  #: median edge length
    sensor_range: float
    transitions: pl.DataFrame  #: the counted transitions when the graph was learned, else empty


def _casas_graph(parts: _CasasParts, lay: Layout | None, *, window_s, min_count, min_share, spacing_m) -> _CasasGraph:
    """Positions and edges: the layout's when it gives them, edges from its geometry when it
    can, else learned from the log (:func:`learn_sensor_graph`); positions without a layout are
    a force layout (module docstring)."""
    trans = pl.DataFrame()
    if lay is not None:
        positions = {
            n: lay.positions[n] for n in sorted(lay.positions, key=_natural) if n in parts.nodes or not lay.only_logged
        }
        edges = sorted({(min(a, b), max(a, b)) for a, b in lay.edges}) if lay.edges is not None else None
        units, how = lay.units, "layout file"
    else:
        positions, edges, units, how = None, None, "m", "force layout"
    graph_how = "layout file"
    if edges is None and lay is not None and lay.graph is not None:
        edges, graph_how = lay.graph(positions), "geometry"
    if edges is None:
        edges, trans = learn_sensor_graph(
            parts.toggles, parts.nodes, window_s=window_s, min_count=min_count, min_share=min_share
        )
        graph_how = "learned"
    if positions is None:
        positions = force_layout(parts.nodes, edges, spacing=spacing_m)
    spacing = _median_edge(positions, edges) or spacing_m
    sensor_range = lay.range if lay is not None and lay.range is not None else round(spacing / 2.0, 3)
    rule = (
        "consecutive ON/OPEN events of two sensors at most window_s apart are a transition; an edge needs "
        ">= min_count transitions making >= min_share of the less busy sensor's, at least min_lift times what "
        "chance would give; components joined by a "
        "maximum spanning forest of the counts (transitions.csv)"
        if graph_how == "learned"
        else (lay.graph_rule if graph_how == "geometry" else "from the layout file")
    )
    return _CasasGraph(positions, edges, units, how, graph_how, rule, spacing, sensor_range, trans)


def _write_casas_tables(out: Path, parts: _CasasParts, res: CasasLog, trans: pl.DataFrame) -> None:
    """``motion.csv`` and, when they have rows, ``truth_events.csv``, ``other.csv``,
    ``annotations.csv``, ``rejects.csv``, ``annotation_problems.csv``, ``lost_offs.csv``,
    ``transitions.csv`` (``t`` rounded to the microsecond)."""
    t = pl.col("t").round(6)
    write_csv(
        parts.toggles.select(
            t, "sensor", "value", "stamp", pl.col("line").alias("log_line"), pl.col("repaired").cast(pl.Int8)
        ),
        out / "motion.csv",
    )
    if parts.truth_events.height:
        write_csv(parts.truth_events.select(t, "sensor", "residents"), out / "truth_events.csv")
    if parts.others.height:
        write_csv(
            parts.others.select(t, "sensor", "kind", "value", "stamp", pl.col("line").alias("log_line")),
            out / "other.csv",
        )
    if parts.notes.height:
        write_csv(
            parts.notes.select(
                t,
                "sensor",
                "value",
                "annotation",
                "residents",
                "tasks",
                "activity",
                "activity_edge",
                "stamp",
                pl.col("line").alias("log_line"),
            ),
            out / "annotations.csv",
        )
    if res.rejects.height:
        write_csv(res.rejects.select(REJECTS.names()), out / "rejects.csv")
    if res.annotation_problems.height:
        write_csv(res.annotation_problems.select(REJECTS.names()), out / "annotation_problems.csv")
    if parts.repairs.height:
        write_csv(parts.repairs, out / "lost_offs.csv")
    if trans.height:
        write_csv(trans, out / "transitions.csv")


def _casas_record(
    log: Path,
    res: CasasLog,
    parts: _CasasParts,
    g: _CasasGraph,
    door_ids: list[str],
    *,
    window_s,
    min_count,
    min_share,
    hold_s,
    hold_samples,
) -> tuple[dict, dict]:
    """``(counts, import.toml)``: what was read, written, repaired and how the graph was found."""
    counts = {
        "lines": res.lines,
        "events": parts.events.height,
        "rejected": res.rejects.height,
        "reordered": res.reordered,
        **{f"kind_{k}": v for k, v in res.kind_counts().items()},
        "motion_csv": parts.toggles.height,
        "lost_off_repaired": parts.repairs.height,
        "other_csv": parts.others.height,
        "annotations": parts.notes.height,
        "annotation_problems": res.annotation_problems.height,
        "truth_events": parts.truth_events.height,
        "sensors": len(g.positions),
        "unplaced_sensors": len(parts.unplaced),
        "doors": len(door_ids),
        "edges": len(g.edges),
    }
    info = {
        "source": {"file": str(log.resolve()), "format": "casas-csv" if log.suffix.lower() == ".csv" else "casas"},
        "counts": counts,
        "time": res.origin.as_dict(),
        "graph": {
            "source": g.graph_how,
            "rule": g.rule,
            "window_s": window_s,
            "min_count": min_count,
            "min_share": min_share,
            "min_lift": MIN_LIFT,
        },
        "doors": {
            "entries_exits": door_ids,
            "rule": "only contacts declared doors by the layout or --doors; other contacts are ordinary nodes",
        },
        "lost_off": {
            "rule": "a repeated ON more than the sensor's hold time after the previous ON gets an OFF at t_prev + hold "
            "(hold = median on-duration with >= hold_samples samples, else hold_s); lost_offs.csv lists them",
            "hold_s": hold_s,
            "hold_samples": hold_samples,
            "repaired": parts.repairs.height,
        },
        "truth_events": {
            "rule": "ON/OPEN events of graph sensors with resident annotations: t, sensor, residents (ids sorted, ';')",
            "rows": parts.truth_events.height,
        },
        "layout": {
            "positions": g.how,
            "spacing": round(g.spacing, 3),
            "range": g.sensor_range,
            "unplaced": parts.unplaced,
        },
    }
    return counts, info


def _renamed(lay: Layout, log_ids) -> Layout:
    """``lay`` with its ids renamed to the log's (:func:`match_ids`: ``M017`` -> ``M17``)."""
    ren = match_ids(list(lay.positions), log_ids)
    if all(k == v for k, v in ren.items()):
        return lay
    from dataclasses import replace

    edges = tuple((ren.get(a, a), ren.get(b, b)) for a, b in lay.edges) if lay.edges is not None else None
    return replace(
        lay,
        positions={ren[k]: v for k, v in lay.positions.items()},
        edges=edges,
        kinds={ren.get(k, k): v for k, v in lay.kinds.items()},
    )


def _median_edge(positions: dict, edges: list) -> float | None:
    d = [math.dist(positions[a], positions[b]) for a, b in edges if a in positions and b in positions]
    d = [x for x in d if x > 0]
    return float(np.median(d)) if d else None


def _epoch_text(res: CasasLog) -> str | None:
    o = res.origin
    if o.source == "none":
        return None
    return o.as_dict()["origin"].removesuffix("Z")


def _natural(s: str):
    return [int(p) if p.isdigit() else p for p in re.split(r"(\d+)", s)]


# --------------------------------------------------------------------------- trajectories


def import_trajectories(file: str | Path, dataset: str | Path, fmt: TrajectoryFormat | None = None) -> ImportSummary:
    """Write ``truth.csv`` of ``dataset`` from a trajectory export (module docstring).

    ``t`` is measured from the dataset's ``site.toml`` ``epoch`` when it has one, else from
    the export's first second; a new ``site.toml`` (only when the folder has none) holds the
    walks' bounding box grown by 1 site unit, ``units = "m"``, no sensors yet, and the epoch
    when the export's times are absolute (ISO, or numbers from 1e8 s on: Unix time)."""
    file, out = Path(file), Path(dataset)
    if not file.is_file():
        raise InputError("no such trajectory file", file=file)
    site_path = out / "site.toml"
    site = load_site(site_path) if site_path.exists() else None
    res = read_trajectories(file, fmt, epoch=site.epoch if site is not None else None)
    if res.truth.height == 0:
        raise InputError(
            f"no readable position (rejected: {res.rejects.height} rows; first: "
            f"{res.rejects['reason'][0] if res.rejects.height else 'none'})",
            file=file,
        )
    out.mkdir(parents=True, exist_ok=True)
    made_site = site is None
    if made_site:
        tr = res.truth
        x0, x1 = float(tr["x"].min()) - 1.0, float(tr["x"].max()) + 1.0
        y0, y1 = float(tr["y"].min()) - 1.0, float(tr["y"].max()) + 1.0
        absolute = res.time_unit == "iso" or abs(res.origin.origin) >= 1e8
        lines = [
            f"# Written by 'onebit import trajectories' from {file.name}: the walks' bounding box.",
            "# Add the sensors to plan (beams, motion_sensors, proximity_sensors), then: onebit simulate from-truth DIR",
            f"name = {_v(out.name or 'trajectories')}",
            'units = "m"',
        ]
        if absolute:
            lines.append(f"epoch = {_v(res.origin.as_dict()['origin'].removesuffix('Z'))}")
        lines += ["", "[boundary]", f"polygon = {_v([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])}", ""]
        text = "\n".join(lines)
        site_from_dict(tomllib.loads(text), source=str(site_path))
        write_text(text, site_path)
    write_csv(res.truth.select("t", "target", "x", "y"), out / "truth.csv")
    if res.rejects.height:
        write_csv(res.rejects, out / "truth_rejects.csv")
    counts = {
        "rows": res.truth.height + res.rejects.height,
        "positions": res.truth.height,
        "rejected": res.rejects.height,
        "tracks": res.truth["target"].n_unique(),
        "joined_rows": res.joined,
    }
    fmt = fmt or TrajectoryFormat()
    info = {
        "source": {
            "file": str(file.resolve()),
            "format": "trajectories",
            "columns": res.columns,
            "time_unit": res.time_unit,
        },
        "counts": counts,
        "time": res.origin.as_dict(),
        "transform": {
            "scale": fmt.scale,
            "offset": list(fmt.offset),
            "flip_x": fmt.flip_x,
            "flip_y": fmt.flip_y,
            "swap_xy": fmt.swap_xy,
            "join": [",".join(g) for g in fmt.join],
        },
        "site": {"written": made_site},
    }
    write_text(to_toml(info), out / "truth_import.toml")
    return ImportSummary(out, counts, info)
