"""Binary toggle logs (``motion.csv``, ``proximity.csv``: t, sensor, value) -> accepted edges.

A raw PIR log is a list of state changes (``value`` 1 = on, 0 = off) per sensor, with the
faults of cheap relays. The reader works in three passes, all polars expressions over the
whole log (no Python loop over rows):

1. **Typing** (:func:`onebit.readers.rows.check_rows`): malformed ``t`` / ``value`` (any
   spelling of :data:`TOGGLE_VALUES`), an unknown sensor, a row identical to an earlier one
   (duplicate) and a row whose ``t`` is more than ``tolerance`` (1 s) earlier than an accepted
   row before it (out of order) go to ``rejects``; rows less far out of order are sorted into
   place and counted (``reordered``).
2. **State changes.** Every sensor starts off. An edge that does not change its sensor's state
   (``1`` while already on, ``0`` while already off) cannot be a transition and goes to
   ``rejects`` ("no state change") -- unless the sensor's reading is a *level* (``held``: a
   sensor held on is presence, :data:`onebit.core.site.SIGNALS`): a level log may repeat its
   state at every sample (one 0/1 per sensor per frame), so a repeat is a held state, counted
   (``MotionRead.held``) and dropped as carrying no edge. Removing every edge equal to its predecessor leaves an
   alternating sequence ``on, off, on, ...`` per sensor (a run-length compression), so one
   pass suffices.
3. **Debounce** (:class:`DebounceRules`, per sensor or per sensor type), on that alternating
   sequence, in this order:

   * *relay chatter* (Singh et al.'s experiment): an off edge at ``t_off`` followed by the
     sensor's next edge, an on edge at ``t_on``, with ``t_on - t_off <= chatter_window``:
     both edges are suppressed (the sensor is taken to have stayed on);
   * *minimum on-time*: an on edge at ``t_on`` followed by its off edge at ``t_off`` with
     ``t_off - t_on < min_on``: both edges are suppressed (the pulse is taken as noise). An
     on-period still open at the end of the log has no known length and is kept.

   Each rule removes (off, on) or (on, off) pairs of consecutive edges, so the sequence stays
   alternating; removing a short on-pulse only lengthens off-gaps, so it never creates new
   chatter, and one pass of each rule is exact. Suppressed edges go to ``suppressed`` with
   the rule's name; nothing is lost: accepted + rejected + suppressed + held = input rows.

The trackers sample the accepted edges on slots of their own period with
:func:`onebit.core.frames.motion_frames` (the base layer: no tracker imports a reader).

Examples
--------
>>> import polars as pl
>>> from onebit.readers.rows import RawRows
>>> from onebit.core.tables import REJECTS
>>> frame = pl.DataFrame({"line": [2, 3, 4, 5], "t": ["0", "1.0", "1.05", "3"],
...                       "sensor": ["p1"] * 4, "value": ["1", "0", "1", "0"],
...                       "raw": [None] * 4}, schema_overrides={"line": pl.Int64, "raw": pl.String})
>>> res = read_motion(RawRows("motion.csv", frame, pl.DataFrame(schema=REJECTS)), ["p1"],
...                   rules=DebounceRules(chatter_window=0.1))
>>> res.motion["t"].to_list(), res.suppressed["rule"].to_list()
([0.0, 3.0], ['chatter', 'chatter'])
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.compiled import numba_loaded
from onebit.core.errors import ConfigError
from onebit.core.params import param, validate
from onebit.core.tables import MOTION, REJECTS, conform
from onebit.readers import kernels
from onebit.readers.logs import CsvLog, csv_path, typed_read
from onebit.readers.rows import (
    REORDER_TOLERANCE_S,
    RawRows,
    TypedRows,
    by_time,
    check_rows,
    check_split,
    clean_time,
    in_time_order,
    kept_rows,
    make_rejects,
    order_checks,
    parse_choice,
    parse_name,
    parse_time,
    read_clean_csv,
    read_csv_rows,
)
from onebit.readers.timebase import TimeOrigin

#: Columns of a toggle log.
TOGGLE_COLUMNS = ("t", "sensor", "value")

#: Accepted spellings of a toggle value, in any letter case: ``1``/``0``, ``on``/``off``,
#: ``true``/``false``, ``open``/``close`` (door sensors, CASAS ``D###``: open = activity),
#: ``present``/``absent`` (presence sensors); an unreadable value is a reject naming them.
TOGGLE_VALUES = {
    "1": True,
    "0": False,
    "1.0": True,
    "0.0": False,
    "on": True,
    "off": False,
    "true": True,
    "false": False,
    "open": True,
    "close": False,
    "closed": False,
    "present": True,
    "absent": False,
}

#: Tolerance (s) of the debounce comparisons, so a gap of exactly the window counts as inside it
#: despite floating-point rounding of the time stamps.
TIME_EPS = 1e-9

#: Schema of the ``suppressed`` table: edges removed by a debounce rule.
SUPPRESSED = pl.Schema({"t": pl.Float64, "sensor": pl.String, "on": pl.Boolean, "rule": pl.String, "line": pl.Int64})


@dataclass(frozen=True, kw_only=True)
class DebounceRules:
    """Debounce rules of one sensor (type). The defaults change nothing.

    Every field is in seconds, finite and >= 0.
    """

    chatter_window: float = (
        0.0  #: s; a 1->0 followed by 0->1 on the same sensor within this window: both edges suppressed
    )
    min_on: float = 0.0  #: s; an on-period shorter than this is suppressed (both its edges)

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ConfigError(f"DebounceRules.{f.name} = {v!r}: must be a finite number >= 0 (seconds)")
            object.__setattr__(self, f.name, float(v))

    @classmethod
    def from_mapping(cls, data: Mapping[str, object] | None, *, section: str = "motion") -> DebounceRules:
        """Rules from a config table (e.g. run.toml ``[motion]``); other keys are ignored."""
        data = dict(data or {})
        names = {f.name for f in fields(cls)}
        kwargs = {k: v for k, v in data.items() if k in names}
        try:
            return cls(**kwargs)
        except ConfigError as exc:
            raise ConfigError(f"[{section}] {exc}") from None


def rules_by_type(
    sensor_types: Mapping[str, str],
    by_type: Mapping[str, DebounceRules],
    default: DebounceRules | None = None,
) -> dict[str, DebounceRules]:
    """Per-sensor rules from per-type rules: ``sensor_types`` maps sensor id -> type name.

    Sensors whose type has no rules get ``default`` (no-op rules when ``None``).
    """
    default = default or DebounceRules()
    return {sid: by_type.get(typ, default) for sid, typ in sensor_types.items()}


@dataclass(frozen=True)
class MotionRead:
    """What :func:`read_motion` made of a toggle log."""

    motion: pl.DataFrame  # MOTION schema (t, sensor, on), accepted edges, sorted by t
    rejects: pl.DataFrame  # REJECTS schema (source, line, reason, raw)
    suppressed: pl.DataFrame  # SUPPRESSED: t, sensor, on, rule, line
    reordered: int = 0  # accepted rows that came out of order (within the tolerance) and were sorted
    held: int = 0  # repeats of a level sensor's state (a sampled log): no edge, not a fault


def read_motion(
    raw: RawRows | Path | CsvLog,
    sensors: Sequence[str],
    *,
    epoch: str | TimeOrigin | None = None,
    path: Path | None = None,
    rules: DebounceRules | Mapping[str, DebounceRules] | None = None,
    tolerance: float = REORDER_TOLERANCE_S,
    held: frozenset[str] | set[str] = frozenset(),
) -> MotionRead:
    """Type, check and debounce a toggle log: the toggle reader.

    Parameters
    ----------
    raw : the log (:data:`~onebit.readers.logs.Log`): a CSV file, read by :func:`read_motion_csv`
        (typed in one read, line by line only where it must), or string rows with columns
        ``t``, ``sensor``, ``value`` (an MCAP channel's, or :func:`~onebit.readers.rows.read_csv_rows`').
    sensors : the known sensor ids; any other id is rejected.
    epoch : the run's :class:`~onebit.readers.timebase.TimeOrigin`, or the site's epoch (for
        ISO wall-clock stamps) when the reader is used on its own.
    path : the CSV file, so rejects carry the raw line text.
    tolerance : rows at most this many seconds out of order are sorted into place and counted
        (``reordered``), not rejected.
    rules : one :class:`DebounceRules` for every sensor, or a mapping sensor id -> rules
        (sensors not in it get no-op rules; see :func:`rules_by_type`).
    held : the sensors whose reading is a level: a repeated state is a held state (counted), not a reject.

    The reasons never name the sensor kind, so the same reader serves ``proximity.csv``.
    """
    sensors = tuple(sensors)
    if not isinstance(raw, RawRows):
        return read_motion_csv(raw, sensors, epoch=epoch, rules=rules, held=held, tolerance=tolerance)
    typed = check_rows(
        raw, _toggle_parsers(sensors, epoch, raw.frame), key=("t", "sensor", "value"), path=path, tolerance=tolerance
    )
    return toggle_edges(typed, sensors, source=raw.source, path=path, rules=rules, held=held)


def _toggle_parsers(sensors: tuple[str, ...], epoch, frame: pl.DataFrame) -> dict[str, tuple[pl.Expr, pl.Expr]]:
    return {
        "t": parse_time("t", epoch, frame),
        "sensor": parse_name("sensor", sensors, "sensor"),
        "value": parse_choice("value", TOGGLE_VALUES, pl.Boolean, case_insensitive=True),
    }


def toggle_edges(
    typed: TypedRows,
    sensors: tuple[str, ...],
    *,
    source: str,
    path: Path | None,
    rules: DebounceRules | Mapping[str, DebounceRules] | None,
    held: frozenset[str] | set[str] = frozenset(),
) -> MotionRead:
    """Passes 2 and 3 of :func:`read_motion` on typed and checked rows (``t``, ``sensor``, ``value``)."""
    ok, rejects = typed.accepted, typed.rejects
    ok = ok.rename({"value": "on"})  # sorted by t, file order within a stamp (TypedRows)
    masks = _toggle_masks(ok, sensors, rules)

    # pass 2: edges that do not change their sensor's state (every sensor starts off)
    if masks is None:
        same = repeats(ok)
    else:  # (a log without repeats, the usual one: no Series of them)
        same = pl.Series(masks[0]) if masks[0].any() else None
    n_held = 0
    if held and same is not None and same.any():  # a level sensor's repeated state is a held state: no edge, no fault
        is_held = ok.select(pl.col("sensor").cast(pl.String).is_in(list(held))).to_series() & same
        n_held = int(is_held.sum())
        ok, same = ok.filter(~is_held), same.filter(~is_held)
        if masks is not None:
            masks = tuple(mk[~is_held.to_numpy()] for mk in masks)
    if same is not None and same.any():  # reasons for those edges only
        rep = (
            ok.filter(same)
            .rechunk()
            .with_columns(
                pl.when(pl.col("on"))
                .then(pl.format("no state change: sensor {} already on", pl.col("sensor")))
                .otherwise(pl.format("no state change: sensor {} already off", pl.col("sensor")))
                .alias("_reason")
            )
        )
        more = make_rejects(rep, source, path, typed.file)
        rejects = pl.concat([rejects, more]).sort("line")
        ok = ok.filter(~same)
        if masks is not None:
            masks = tuple(mk[~masks[0]] for mk in masks)

    # pass 3: debounce on the alternating sequence
    if masks is not None:  # the typed read's codes and the numpy masks: both tables in one go
        motion, suppressed = _motion_tables(ok, masks[1], masks[2])
        return MotionRead(
            motion, rejects.select(REJECTS.names()).cast(dict(REJECTS)), suppressed, typed.reordered, n_held
        )
    edges, suppressed = debounce(ok, sensors, rules)
    if isinstance(edges.schema["sensor"], pl.Enum):  # the typed read's codes: names gathered, not cast row by row
        names = pl.Series(edges.schema["sensor"].categories, dtype=pl.String)
        motion = pl.DataFrame(
            {"t": edges["t"], "sensor": names.gather(edges["sensor"].to_physical()), "on": edges["on"]}, schema=MOTION
        )
    else:
        motion = conform(edges, MOTION)
    return MotionRead(motion, rejects.select(REJECTS.names()).cast(dict(REJECTS)), suppressed, typed.reordered, n_held)


def _toggle_masks(ok: pl.DataFrame, sensors: Sequence[str], rules) -> tuple[np.ndarray, ...] | None:
    """Passes 2 and 3's masks (repeat, chatter, short) of typed edges in time order, by one numpy
    pass (:func:`~onebit.readers.kernels.toggle_masks_vectorised`: one sort by sensor for the
    repeats and the debounce) when the edges are the typed read's (sensor codes of an enum) and
    numba is not loaded in the process (at any size: at 10^4 edges it takes a third of the
    polars references' time); else ``None``: :func:`repeats` and :func:`debounce` (the kernels
    when numba is loaded, from :data:`~onebit.readers.kernels.MIN_ROWS` edges, the polars
    references below) make them, with the same result."""
    if numba_loaded() or not isinstance(ok.schema["sensor"], pl.Enum):
        return None
    if not (in_time_order(ok["t"]) and in_time_order(ok["line"])):
        return None
    names = ok.schema["sensor"].categories.to_list()
    table = _rules_frame(sensors, rules)
    chatter = dict(zip(table["sensor"].to_list(), table["_chatter"].to_list()))
    min_on = dict(zip(table["sensor"].to_list(), table["_min_on"].to_list()))
    return kernels.toggle_masks_vectorised(
        ok["sensor"].to_physical().to_numpy(),
        ok["on"].to_numpy(),
        ok["t"].to_numpy(),
        np.array([chatter.get(n, 0.0) for n in names], dtype=np.float64),
        np.array([min_on.get(n, 0.0) for n in names], dtype=np.float64),
        max(len(names), 1),
        TIME_EPS,
    )


def repeats(ok: pl.DataFrame, *, compiled: bool | None = None) -> pl.Series:
    """Which edges (``sensor``, ``on``; in time order) repeat their sensor's state: one compiled
    pass (:func:`onebit.readers.kernels.toggle_repeats`) from
    :data:`~onebit.readers.kernels.MIN_ROWS` edges on (``compiled=None``), else its reference,
    a polars ``shift`` over each sensor (same result)."""
    if not (ok.height >= kernels.MIN_ROWS if compiled is None else compiled):
        return ok.select(pl.col("on") == pl.col("on").shift(1).over("sensor").fill_null(False)).to_series()
    if isinstance(ok.schema["sensor"], pl.Enum):
        code, n = ok["sensor"].to_physical().to_numpy().astype(np.int64), ok.schema["sensor"].categories.len()
    else:
        names = ok["sensor"].unique(maintain_order=True)
        code, n = (
            ok["sensor"].replace_strict(names, range(len(names)), return_dtype=pl.Int64).to_numpy().astype(np.int64),
            len(names),
        )
    run = (
        kernels.toggle_repeats if compiled or numba_loaded() else kernels.toggle_repeats_vectorised
    )  # numba's load only when paid already
    return pl.Series(run(code, ok["on"].to_numpy().astype(np.bool_), max(n, 1)))


#: The same reader under the name the proximity sensors use (``proximity.csv``: t, sensor, value).
read_toggles = read_motion


def _rules_frame(sensors: Sequence[str], rules) -> pl.DataFrame:
    if rules is None:
        rules = DebounceRules()
    if isinstance(rules, DebounceRules):
        per = {s: rules for s in sensors}
    else:
        per = {s: rules.get(s, DebounceRules()) for s in sensors}
        for k, v in rules.items():
            if not isinstance(v, DebounceRules):
                raise ConfigError(f"rules[{k!r}] must be DebounceRules, got {type(v).__name__}")
    return pl.DataFrame(
        {
            "sensor": list(per),
            "_chatter": [r.chatter_window for r in per.values()],
            "_min_on": [r.min_on for r in per.values()],
        },
        schema={"sensor": pl.String, "_chatter": pl.Float64, "_min_on": pl.Float64},
    )


def debounce(
    edges: pl.DataFrame,
    sensors: Sequence[str],
    rules: DebounceRules | Mapping[str, DebounceRules] | None,
    *,
    compiled: bool | None = None,
) -> tuple[pl.DataFrame, pl.DataFrame]:
    """Apply the chatter and minimum-on rules to alternating edges (``line``, t, sensor, on).

    Returns ``(kept, suppressed)``; ``kept`` is sorted by ``t`` (file order within a stamp).
    The rules run as one compiled pass per rule over the edges
    (:func:`onebit.readers.kernels.debounce_masks`); :func:`debounce_reference` (polars
    window expressions) is its plain reference and test oracle. ``compiled=None`` uses the
    kernel from :data:`~onebit.readers.kernels.MIN_ROWS` edges on, the reference below.
    """
    if not (edges.height >= kernels.MIN_ROWS if compiled is None else compiled):
        return debounce_reference(edges, sensors, rules)
    table = _rules_frame(sensors, rules)
    ev = by_time(edges)
    if isinstance(ev.schema["sensor"], pl.Enum):  # the clean path's sensors: their codes are the enum's
        names = ev.schema["sensor"].categories.to_list()
        code = ev["sensor"].to_physical().to_numpy().astype(np.int64)
    else:
        names = ev["sensor"].unique(maintain_order=True).to_list()
        code = ev["sensor"].replace_strict(names, range(len(names)), return_dtype=pl.Int64).to_numpy().astype(np.int64)
    chatter = dict(zip(table["sensor"].to_list(), table["_chatter"].to_list()))
    min_on = dict(zip(table["sensor"].to_list(), table["_min_on"].to_list()))
    masks = (
        kernels.debounce_masks if compiled or numba_loaded() else kernels.debounce_masks_vectorised
    )  # numba's load only when paid already
    chat, short = masks(
        code,
        ev["on"].to_numpy().astype(np.bool_),
        ev["t"].to_numpy().astype(np.float64),
        np.array([chatter.get(n, 0.0) for n in names], dtype=np.float64),
        np.array([min_on.get(n, 0.0) for n in names], dtype=np.float64),
        len(names),
        TIME_EPS,
    )
    return _debounced(ev, chat, short)


def _motion_tables(ev: pl.DataFrame, chat: np.ndarray, short: np.ndarray) -> tuple[pl.DataFrame, pl.DataFrame]:
    """``(motion, suppressed)`` of edges in time order whose sensor is the typed read's enum,
    from the debounce's masks: :func:`_debounced`'s tables in their final schemas, the sensor
    names gathered by code (faster than a String cast of an enum) in one lazy select each."""
    names = pl.Series(ev.schema["sensor"].categories, dtype=pl.String)
    gone = chat | short  # the rules mark disjoint edges (minimum on-time only among those chatter left)
    coded = ev.select("line", "t", pl.col("sensor").to_physical().alias("_s"), "on").lazy()
    sensor = pl.lit(names).gather("_s").alias("sensor")
    if not gone.any():
        return coded.select("t", sensor, "on").collect(), pl.DataFrame(schema=SUPPRESSED)
    kept = ~gone
    motion = coded.filter(pl.Series(kept)).select(sensor, "on")  # its times kept in numpy (kept_rows)
    rule = pl.when(pl.Series(chat[gone])).then(pl.lit("chatter")).otherwise(pl.lit("min_on")).alias("rule")
    suppressed = coded.filter(pl.Series(gone)).select("t", sensor, "on", rule, "line")  # in time order, as ev
    motion, suppressed = pl.collect_all([motion, suppressed])
    return motion.insert_column(0, kept_rows(ev["t"], kept)), suppressed


def _debounced(ev: pl.DataFrame, chat: np.ndarray, short: np.ndarray) -> tuple[pl.DataFrame, pl.DataFrame]:
    """``(kept, suppressed)`` of :func:`debounce` from its masks over ``ev`` (edges in time order)."""
    ev = ev.select("line", "t", "sensor", "on")
    gone = chat | short  # the rules mark disjoint edges (minimum on-time only among those chatter left)
    kept = ev.filter(pl.Series(~gone))  # still sorted by t, line
    sup = ev.filter(pl.Series(gone)).with_columns(  # in time order, as ev
        rule=pl.when(pl.Series(chat[gone])).then(pl.lit("chatter")).otherwise(pl.lit("min_on"))
    )
    return kept, conform(sup, SUPPRESSED)


def debounce_reference(
    edges: pl.DataFrame,
    sensors: Sequence[str],
    rules: DebounceRules | Mapping[str, DebounceRules] | None,
) -> tuple[pl.DataFrame, pl.DataFrame]:
    """:func:`debounce` with polars window expressions (``shift`` over each sensor): the plain
    reference of the compiled kernel and its test oracle."""
    table = _rules_frame(sensors, rules)
    ev = (
        edges.with_columns(pl.col("sensor").cast(pl.String))
        .sort(["t", "line"])
        .join(table, on="sensor", how="left")
        .with_columns(pl.col("_chatter").fill_null(0.0), pl.col("_min_on").fill_null(0.0))
    )
    nxt_t = pl.col("t").shift(-1).over("sensor", order_by=["t", "line"])
    prv_t = pl.col("t").shift(1).over("sensor", order_by=["t", "line"])
    prv_on = pl.col("on").shift(1).over("sensor", order_by=["t", "line"])
    nxt_on = pl.col("on").shift(-1).over("sensor", order_by=["t", "line"])

    # chatter: (off at t_k, on at t_{k+1}) with t_{k+1} - t_k <= window, window > 0
    chatter = (pl.col("_chatter") > 0) & (
        (~pl.col("on") & nxt_on.fill_null(False) & ((nxt_t - pl.col("t")) <= pl.col("_chatter") + TIME_EPS))
        | (pl.col("on") & (prv_on == False) & ((pl.col("t") - prv_t) <= pl.col("_chatter") + TIME_EPS))  # noqa: E712
    )
    ev = ev.with_columns(chatter.fill_null(False).alias("_chat"))
    sup_chat = ev.filter(pl.col("_chat")).with_columns(rule=pl.lit("chatter"))
    ev = ev.filter(~pl.col("_chat"))

    # minimum on-time: (on at t_k, off at t_{k+1}) with t_{k+1} - t_k < min_on
    short = (pl.col("_min_on") > 0) & (
        (pl.col("on") & (nxt_on == False) & ((nxt_t - pl.col("t")) < pl.col("_min_on") - TIME_EPS))  # noqa: E712
        | (~pl.col("on") & prv_on.fill_null(False) & ((pl.col("t") - prv_t) < pl.col("_min_on") - TIME_EPS))
    )
    ev = ev.with_columns(short.fill_null(False).alias("_short"))
    sup_short = ev.filter(pl.col("_short")).with_columns(rule=pl.lit("min_on"))
    kept = ev.filter(~pl.col("_short")).select("line", "t", "sensor", "on").sort(["t", "line"])
    suppressed = conform(
        pl.concat([sup_chat.drop("_short", strict=False), sup_short], how="diagonal"), SUPPRESSED
    ).sort(["t", "line"])
    return kept, suppressed


def read_motion_csv(
    path: str | Path | CsvLog,
    sensors: Sequence[str],
    *,
    epoch: str | TimeOrigin | None = None,
    rules: DebounceRules | Mapping[str, DebounceRules] | None = None,
    held: frozenset[str] | set[str] = frozenset(),
    tolerance: float = REORDER_TOLERANCE_S,
) -> MotionRead:
    """Read ``motion.csv`` (or ``proximity.csv``): the whole toggle reader for one file, typed
    in one read (:func:`typed_toggle_rows`), the row-by-row path when that read cannot take it."""
    log, path = path, csv_path(path)
    sensors = tuple(sensors)
    typed = typed_toggle_rows(log, sensors, epoch=epoch, tolerance=tolerance)
    if typed is None:
        raw = read_csv_rows(path, TOGGLE_COLUMNS)
        return read_motion(raw, sensors, epoch=epoch, path=path, rules=rules, held=held, tolerance=tolerance)
    return toggle_edges(typed, sensors, source=path.name, path=path, rules=rules, held=held)


def toggle_dtypes(sensors: Sequence[str]) -> dict[str, pl.DataType]:
    """The typed read of a toggle log: numeric ``t``, known sensors, values as :data:`TOGGLE_VALUES` spells them."""
    return {"t": pl.Float64, "sensor": pl.Enum(list(dict.fromkeys(sensors))), "value": pl.Enum(list(TOGGLE_VALUES))}


def typed_toggle_rows(
    path: Path | CsvLog,
    sensors: tuple[str, ...],
    *,
    epoch: str | TimeOrigin | None = None,
    tolerance: float = REORDER_TOLERANCE_S,
) -> TypedRows | None:
    """Pass 1 of :func:`read_motion` for a toggle log typed by one ``pl.read_csv``
    (:func:`~onebit.readers.rows.read_typed_csv`, the one its :class:`~onebit.readers.logs.CsvLog`
    kept: :func:`~onebit.readers.logs.typed_read`; numeric ``t``, known sensors, values spelled
    as in :data:`TOGGLE_VALUES`, lower case); the lines it cannot take are typed row by row.
    ``None`` when the header is not a plain first line (the row-by-row path reads the file).
    The sensor stays an enum (the debounce's codes); every output table casts it to String."""
    spellings = list(TOGGLE_VALUES)
    split = typed_read(path, toggle_dtypes(sensors))
    if split is None:
        return None
    on_codes = [i for i, v in enumerate(spellings) if TOGGLE_VALUES[v]]  # the spellings of "on", by code
    good = split.good.with_columns(pl.col("value").to_physical().is_in(on_codes).alias("value"))
    return check_split(
        split,
        good,
        lambda origin, frame: _toggle_parsers(sensors, origin, frame),
        key=TOGGLE_COLUMNS,
        tolerance=tolerance,
        epoch=epoch,
        path=csv_path(path),
    )


def clean_toggle_rows(
    path: Path,
    sensors: tuple[str, ...],
    *,
    epoch: str | TimeOrigin | None = None,
    tolerance: float = REORDER_TOLERANCE_S,
) -> TypedRows | None:
    """Pass 1 of :func:`read_motion` for a clean toggle log (:func:`~onebit.readers.rows.read_clean_csv`:
    numeric ``t``, known sensors, values spelled as in :data:`TOGGLE_VALUES`, lower case),
    typed by one ``pl.read_csv``; ``None`` when a row would be rejected by its fields (the
    row-by-row path names it). Duplicates and rows out of order are found as for any file."""
    spellings = list(TOGGLE_VALUES)
    frame = read_clean_csv(
        path, {"t": pl.Float64, "sensor": pl.Enum(list(dict.fromkeys(sensors))), "value": pl.Enum(spellings)}
    )
    if frame is None:
        return None
    t = clean_time(frame["t"], epoch)
    if t is None:
        return None
    on = pl.Series([TOGGLE_VALUES[v] for v in spellings], dtype=pl.Boolean)
    # sensor stays an enum (the debounce's codes); every output table casts it to String
    frame = frame.with_columns(t, on.gather(frame["value"].to_physical()).alias("value"))
    return order_checks(
        frame, key=TOGGLE_COLUMNS, tolerance=tolerance, columns=TOGGLE_COLUMNS, source=path.name, path=path
    )


# --------------------------------------------------------------------------- reader config


@dataclass(frozen=True, kw_only=True)
class MotionConfig:
    """``run.toml`` ``[motion]``: the debounce of every motion sensor."""

    chatter_window: float | None = param(
        None, "relay-chatter window for every sensor; unset = from the sensor type", lo=0.0, unit="s"
    )
    min_on: float | None = param(
        None, "minimum on-time for every sensor; unset = from the sensor type", lo=0.0, unit="s"
    )

    def __post_init__(self) -> None:
        validate(self)


def site_rules(site, cfg: MotionConfig) -> dict[str, DebounceRules]:
    """Per-sensor debounce rules: the sensor type's, overridden by ``cfg`` where set."""
    out: dict[str, DebounceRules] = {}
    for ms in site.motion_sensors:
        typ = site.sensor_types.get(ms.type, {}) if isinstance(site.sensor_types, dict) else {}
        vals = {k: typ[k] for k in ("chatter_window", "min_on") if k in typ}
        for k in ("chatter_window", "min_on"):
            if getattr(cfg, k) is not None:
                vals[k] = getattr(cfg, k)
        try:
            out[ms.id] = DebounceRules(**vals)
        except ConfigError as exc:
            raise ConfigError(f"site.toml [sensor_types.{ms.type}]: {exc}") from None
    return out
