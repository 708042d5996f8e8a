"""Raw directional-beam log -> crossings, through the bidirectional-beam state machine.

Bobadilla et al., section VI-A, Figs. 5-7: each directional beam is two emitter-detector
pairs a few cm apart, ``a`` on the backward side and ``b`` on the forward side. A body wider
than the spacing that crosses forward blocks ``a``, then both, then only ``b``, then none;
backward is the mirror image; a body that starts to cross and returns clears the pair it
blocked first, last.

Decoding (the Fig. 7 machine, written so that it also survives detector jitter). Per beam,
let ``s_k = (A_k, B_k)`` be the pair states after event ``k`` (forward-filled per pair, both
clear initially). A *pass* is a maximal run of events between two idle states (0, 0). With
``first`` the pair whose edge opened the pass and ``last`` the pair whose clearing closed it::

    first = a, last = b  ->  crossing, direction +1 (forward), at the time of the last edge
    first = b, last = a  ->  crossing, direction -1 (backward)
    first = last         ->  start-and-return: no crossing, counted as aborted

For a clean pass this is exactly the machine of Fig. 7 (IDLE -a-> A -ab-> AB -b-> B -idle->
emit). A pass still open at the end of the log is reported as unfinished.

Everything is vectorised with polars window expressions over beams; nothing loops over rows.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.compiled import numba_loaded
from onebit.core.sensing import body_radius
from onebit.core.tables import ABORTED, BEAM_EVENTS, CROSSINGS, REJECTS, conform
from onebit.readers import kernels
from onebit.readers.logs import CsvLog, Log, csv_path, typed_read
from onebit.readers.rows import (
    FileLines,
    RawRows,
    TypedRows,
    by_time,
    check_split,
    clean_time,
    kept_rows,
    make_rejects,
    order_checks,
    parse_choice,
    parse_name,
    parse_time,
    raw_lines,
    read_clean_csv,
    read_csv_rows,
    type_rows,
)
from onebit.readers.timebase import TimeOrigin

BEAM_COLUMNS = ("t", "beam", "pair", "blocked")


@dataclass(frozen=True)
class BeamDecode:
    """Result of decoding a raw beam log."""

    events: pl.DataFrame  # accepted events (BEAM_EVENTS + line)
    crossings: pl.DataFrame  # CROSSINGS
    aborted: pl.DataFrame  # ABORTED: start-and-return passes
    unfinished: pl.DataFrame  # beam, t of the last edge of passes still open at the end
    rejects: pl.DataFrame  # REJECTS


def _beam_parsers(beam_ids: tuple[str, ...], epoch, frame: pl.DataFrame) -> dict[str, tuple[pl.Expr, pl.Expr]]:
    return {
        "t": parse_time("t", epoch, frame),
        "beam": parse_name("beam", beam_ids, "beam"),
        "pair": parse_choice("pair", {"a": "a", "b": "b", "A": "a", "B": "b"}, pl.String),
        "blocked": parse_choice(
            "blocked",
            {"1": True, "0": False, "true": True, "false": False, "on": True, "off": False},
            pl.Boolean,
            case_insensitive=True,
        ),
    }


def read_beam_events(raw: RawRows, beam_ids: tuple[str, ...], *, epoch: str | None = None, path: Path | None = None):
    """Type and check raw beam rows: ``t``, known ``beam``, ``pair`` in a|b, ``blocked`` in 0|1."""
    return type_rows(raw, _beam_parsers(beam_ids, epoch, raw.frame), key=("t", "beam", "pair", "blocked"), path=path)


def beam_dtypes(beam_ids: tuple[str, ...]) -> dict[str, pl.DataType]:
    """The typed read of ``beams.csv``: numeric ``t``, known beams, pairs ``a``/``b``, ``blocked`` ``0``/``1``."""
    return {
        "t": pl.Float64,
        "beam": pl.Enum(list(dict.fromkeys(beam_ids))),
        "pair": pl.Enum(["a", "b"]),
        "blocked": pl.Enum(["0", "1"]),
    }


_beam_dtypes = beam_dtypes  # the earlier private name


def typed_beam_events(path: Path | CsvLog, beam_ids: tuple[str, ...], *, epoch=None) -> TypedRows | None:
    """:func:`read_beam_events` of ``beams.csv`` by one typed read (:func:`~onebit.readers.rows.read_typed_csv`;
    the one its :class:`~onebit.readers.logs.CsvLog` kept, :func:`~onebit.readers.logs.typed_read`),
    the lines it cannot take typed row by row; ``None`` when the header is not a plain first
    line (the row-by-row path reads the file). Beam and pair stay enums (the decoder's codes)."""
    split = typed_read(path, beam_dtypes(beam_ids))
    if split is None:
        return None
    good = split.good.with_columns(pl.col("blocked").to_physical() == 1)
    return check_split(
        split,
        good,
        lambda origin, frame: _beam_parsers(beam_ids, origin, frame),
        epoch=epoch,
        key=BEAM_COLUMNS,
        tolerance=0.0,
        path=csv_path(path),
    )


def decode_passes(
    events: pl.DataFrame,
    source: str = "beams.csv",
    *,
    compiled: bool | str | None = None,
    file: FileLines | None = None,
) -> BeamDecode:
    """Decode accepted beam events (``line``, t, beam, pair, blocked; sorted by t) into crossings.

    Edges that do not change their pair's state (blocked while already blocked, or clear
    while clear) cannot come from a body and are rejected with their line. The machine runs
    as one compiled pass over the events (:func:`onebit.readers.kernels.beam_passes`) when numba
    is loaded in the process already (:func:`onebit.core.compiled.numba_loaded`), else as its numpy version (:func:`~onebit.readers.kernels.beam_pass_ends_vectorised`:
    a process that runs no other kernel does not pay numba's load for the reader); the
    tables are built from its result with polars, as :func:`decode_passes_reference` (the
    polars window version, its test oracle) builds them. ``compiled=None``: with numba loaded,
    the kernel from :data:`~onebit.readers.kernels.MIN_ROWS` events on and the reference below;
    without it, the numpy version at any size (at 10^4 events it takes half the reference's
    time); the same result each way. ``True``: the kernel, ``"numpy"``: the numpy version,
    ``False``: the reference. ``file``: the CSV's :class:`~onebit.readers.rows.FileLines` (the
    events' ``line`` numbers are its lines): the rejects get their lines' text from it.
    """
    if compiled is None:  # the kernel where numba is loaded (from MIN_ROWS events), else numpy
        compiled = (events.height >= kernels.MIN_ROWS) if numba_loaded() else "numpy"
    if not compiled:
        return decode_passes_reference(events, source)
    ev = by_time(events)
    names, code_s, pair_s = _beam_codes(ev)
    code, pair = code_s.to_numpy(), pair_s.to_numpy().astype(np.int8)
    blocked = ev["blocked"].to_numpy().astype(np.bool_)
    # ``compiled=None``: numba's load only when a kernel paid it already, else the numpy version
    if compiled is True:
        ends = kernels.pass_ends(*kernels.beam_passes(code.astype(np.int64), pair, blocked, len(names)))
        reject = ends.reject
    else:
        reject = kernels.beam_rejects(code, pair, blocked, len(names))
    bad = np.flatnonzero(reject)
    # the accepted edges, their names gathered by code (faster than a String cast of an enum)
    keep = reject == 0 if bad.size else None
    coded = pl.DataFrame([code_s.alias("_beam"), pair_s.alias("_pair"), ev["blocked"]]).lazy()
    events_q = (coded.filter(pl.Series(keep)) if keep is not None else coded).select(
        pl.lit(names).gather("_beam").alias("beam"),
        pl.lit(pl.Series(["a", "b"], dtype=pl.String)).gather("_pair").alias("pair"),
        pl.col("blocked").cast(pl.Boolean),
    )

    def events_table() -> pl.DataFrame:  # their times kept in numpy (kept_rows): fewer page faults
        return events_q.collect().insert_column(0, kept_rows(ev["t"], keep))

    # a large log: polars builds the events table (and ``file`` names the rejected lines) on a
    # second thread while numpy finds the passes on this one (both free the GIL as they work)
    pool = ThreadPoolExecutor(max_workers=1) if ev.height >= kernels.MIN_ROWS else None
    events_job = pool.submit(events_table) if pool is not None else None
    lines = ev["line"].to_numpy()[bad].tolist() if file is not None else []
    texts_job = pool.submit(file.texts, lines) if pool is not None and lines else None
    try:
        if compiled is not True:
            ends = kernels.beam_pass_ends_vectorised(code, pair, blocked, len(names), reject=reject)
        if bad.size:  # reasons for the rejected edges only
            texts = (lambda: texts_job.result()) if texts_job is not None else (lambda: file.texts(lines))
            rejects = _edge_rejects(ev, reject, bad, source, texts if file is not None else None)
        else:
            rejects = make_rejects(ev.clear().with_columns(pl.lit(None, pl.String).alias("_reason")), source, None)
        events_out = events_job.result() if events_job is not None else events_table()
    finally:
        if pool is not None:
            pool.shutdown()
    return BeamDecode(events_out, *_pass_tables(ev["t"].to_numpy(), names, code, pair, ends), rejects)


def _beam_codes(ev: pl.DataFrame) -> tuple[pl.Series, pl.Series, pl.Series]:
    """(beam names, each event's beam code, its pair's code: ``a`` 0, ``b`` 1): a typed read's
    enum codes as they are, else the beams numbered in order of appearance."""
    if isinstance(ev.schema["beam"], pl.Enum):  # the typed read's beams: their codes are the enum's
        names = pl.Series(ev.schema["beam"].categories, dtype=pl.String)
        code_s = ev["beam"].to_physical()
    else:
        names = ev["beam"].unique(maintain_order=True)
        code_s = ev["beam"].replace_strict(names, range(len(names)), return_dtype=pl.UInt32, default=0)
    if ev.schema["pair"] == pl.Enum(["a", "b"]):
        pair_s = ev["pair"].to_physical()
    else:
        pair_s = (ev["pair"] == "b").cast(pl.UInt8)
    return names, code_s, pair_s


def _edge_rejects(ev: pl.DataFrame, reject: np.ndarray, bad: np.ndarray, source: str, texts) -> pl.DataFrame:
    """The rejects of the edges that did not change their pair's state (``bad``: their rows in
    ``ev``), with their lines' text from ``texts()`` (``None``: no file, no text)."""
    rej = (
        ev[bad]
        .rechunk()
        .with_columns(
            pl.when(pl.Series(reject[bad]) == kernels.ALREADY_BLOCKED)
            .then(pl.format("pair {} of beam {} already blocked (no state change)", pl.col("pair"), pl.col("beam")))
            .otherwise(pl.format("pair {} of beam {} already clear (no state change)", pl.col("pair"), pl.col("beam")))
            .alias("_reason")
        )
    )
    rejects = make_rejects(rej.sort("line"), source, None)
    if texts is not None:  # each line's text, from the file already read
        text = texts()
        rejects = rejects.with_columns(
            pl.Series("raw", [text.get(i) for i in rejects["line"].to_list()], dtype=pl.String)
        )
    return rejects


def _pass_tables(t: np.ndarray, names: pl.Series, code: np.ndarray, pair: np.ndarray, ends) -> tuple:
    """(crossings, aborted, unfinished) from the passes' ends (:func:`~onebit.readers.kernels.pass_ends`)."""
    # closed passes at their closing edge (time order); a crossing leaves by the other pair
    opener, leaver = pair[ends.opened], pair[ends.close]
    crossing = opener != leaver
    cross = ends.close[crossing]
    one, minus = np.int8(1), np.int8(-1)
    crossings = pl.DataFrame(
        {
            "t": t[cross],
            "beam": names.gather(pl.Series(code[cross])),  # (a Series of codes: no conversion of a numpy index)
            "direction": np.where(opener[crossing] == 0, one, minus),
        },
        schema=CROSSINGS,
    )
    tc = t[cross]
    if tc.size > 1 and not (tc[1:] > tc[:-1]).all():  # ties in t: beams in order, else as the passes started
        crossings = crossings.sort(["t", "beam"], maintain_order=True)
    # start-and-return passes: in the order they started (as the reference's groups), then by t
    order = np.argsort(ends.opened[~crossing], kind="stable")
    ab = ends.close[~crossing][order]
    aborted = pl.DataFrame(
        {
            "t": t[ab],
            "beam": names.gather(pl.Series(code[ab])),
            "side": np.where(opener[~crossing][order] == 0, minus, one),
        },
        schema=ABORTED,
    ).sort("t")
    # a pass still open at the end holds its beam's last edge, which does not close it
    op = ends.open_last
    unfinished = pl.DataFrame(
        {"t": t[op], "beam": names.gather(pl.Series(code[op]))}, schema={"t": pl.Float64, "beam": pl.String}
    )
    return crossings, aborted, unfinished


def _decoded(ev: pl.DataFrame, passes: pl.DataFrame, rejects: pl.DataFrame) -> BeamDecode:
    """The reader's tables from the accepted events and their passes (``beam``, ``first`` /
    ``last`` pair, ``closed``, ``t`` of the last edge): a closed pass that left by the other
    pair is a crossing (``a`` first: forward), one that left by the pair it entered is aborted,
    an open one is unfinished."""
    closed = passes.filter(pl.col("closed"))
    crossing = closed.filter(pl.col("first") != pl.col("last")).with_columns(
        direction=pl.when(pl.col("first") == "a").then(1).otherwise(-1).cast(pl.Int8)
    )
    crossings = conform(crossing, CROSSINGS).sort(["t", "beam"], maintain_order=True)
    aborted = conform(
        closed.filter(pl.col("first") == pl.col("last")).with_columns(
            side=pl.when(pl.col("first") == "a").then(-1).otherwise(1).cast(pl.Int8)
        ),
        ABORTED,
    ).sort("t")
    unfinished = passes.filter(~pl.col("closed")).select("t", pl.col("beam").cast(pl.String))
    return BeamDecode(conform(ev, BEAM_EVENTS), crossings, aborted, unfinished, rejects)


def decode_passes_reference(events: pl.DataFrame, source: str = "beams.csv") -> BeamDecode:
    """:func:`decode_passes` with polars window expressions only (forward-filled pair states,
    passes numbered by a cumulative sum of idle states): the plain reference of the compiled
    pass machine and its test oracle."""
    ev = events.sort(["t", "line"])
    prev = pl.col("blocked").shift(1).over(["beam", "pair"]).fill_null(False)
    ev = ev.with_columns(
        pl.when(pl.col("blocked") == prev)
        .then(
            pl.when(pl.col("blocked"))
            .then(pl.format("pair {} of beam {} already blocked (no state change)", pl.col("pair"), pl.col("beam")))
            .otherwise(pl.format("pair {} of beam {} already clear (no state change)", pl.col("pair"), pl.col("beam")))
        )
        .otherwise(None)
        .alias("_reason")
    )
    bad = ev.filter(pl.col("_reason").is_not_null())
    # dropping an edge can make the next edge of the same pair a no-change; iterate to a fixed point
    while bad.height:
        ev = ev.filter(pl.col("_reason").is_null())
        ev = ev.with_columns(
            pl.when(pl.col("blocked") == prev)
            .then(pl.lit("no state change after a rejected edge"))
            .otherwise(None)
            .alias("_reason")
        )
        more = ev.filter(pl.col("_reason").is_not_null())
        if more.height == 0:
            break
        bad = pl.concat([bad, more])
    rejects = make_rejects(bad.sort("line"), source, None)
    ev = ev.drop("_reason")

    state_a = (
        pl.when(pl.col("pair") == "a")
        .then(pl.col("blocked"))
        .otherwise(None)
        .forward_fill()
        .over("beam")
        .fill_null(False)
    )
    state_b = (
        pl.when(pl.col("pair") == "b")
        .then(pl.col("blocked"))
        .otherwise(None)
        .forward_fill()
        .over("beam")
        .fill_null(False)
    )
    ev = ev.with_columns(idle=~state_a & ~state_b)
    ev = ev.with_columns(passno=pl.col("idle").cast(pl.Int64).cum_sum().shift(1).fill_null(0).over("beam"))
    passes = ev.group_by(["beam", "passno"], maintain_order=True).agg(
        first=pl.col("pair").first(),
        last=pl.col("pair").last(),
        closed=pl.col("idle").last(),
        t=pl.col("t").last(),
    )
    return _decoded(ev, passes, rejects)


def read_beams(log: Log, beam_ids: tuple[str, ...], *, epoch: str | TimeOrigin | None = None) -> BeamDecode:
    """The raw-beam reader: ``beams.csv`` (:func:`decode_beam_log`: typed in one read, line by
    line only where it must) or the rows of an MCAP ``/beams`` channel (:func:`decode_raw_beams`),
    decoded into crossings, aborted and unfinished passes, events and rejects."""
    if isinstance(log, RawRows):
        return decode_raw_beams(log, beam_ids, epoch=epoch)
    return decode_beam_log(log, beam_ids, epoch=epoch)


def decode_beam_log(
    path: str | Path | CsvLog, beam_ids: tuple[str, ...], *, epoch: str | TimeOrigin | None = None
) -> BeamDecode:
    """Read ``beams.csv`` and decode it: the whole raw-beam reader.

    The file is typed by one ``pl.read_csv`` (:func:`typed_beam_events`); only the lines it
    cannot take go through the row-by-row CSV layer, which names each bad line. The result is
    the row-by-row path's on the whole file (:func:`decode_raw_beams`)."""
    log, path = path, csv_path(path)
    typed = typed_beam_events(log, tuple(beam_ids), epoch=epoch)
    if typed is None:
        raw = read_csv_rows(path, BEAM_COLUMNS)
        return decode_raw_beams(raw, beam_ids, epoch=epoch, path=path)
    return _decode_events(typed.accepted, typed.rejects, path.name, path, typed.file)


def clean_beam_events(path: Path, beam_ids: tuple[str, ...], *, epoch=None) -> tuple[pl.DataFrame, pl.DataFrame] | None:
    """:func:`read_beam_events` of a clean ``beams.csv`` (:func:`~onebit.readers.rows.read_clean_csv`:
    numeric ``t``, known beams, pairs ``a``/``b``, ``blocked`` ``0``/``1`` as written), as
    ``(events, rejects)``; ``None`` when a row would be rejected by its fields (the row-by-row
    path names it). Duplicates and rows going backwards are found as for any file."""
    frame = read_clean_csv(
        path,
        {
            "t": pl.Float64,
            "beam": pl.Enum(list(dict.fromkeys(beam_ids))),
            "pair": pl.Enum(["a", "b"]),
            "blocked": pl.Enum(["0", "1"]),
        },
    )
    if frame is None:
        return None
    t = clean_time(frame["t"], epoch)
    if t is None:
        return None
    # beam and pair stay enums (the decoder's codes); every output table casts them to String
    frame = frame.with_columns(t, pl.col("blocked").to_physical() == 1)
    res = order_checks(frame, key=BEAM_COLUMNS, tolerance=0.0, columns=BEAM_COLUMNS, source=path.name, path=path)
    return res.accepted, res.rejects


def decode_raw_beams(raw: RawRows, beam_ids, *, epoch=None, path: Path | None = None) -> BeamDecode:
    """Decode string rows (from CSV or an MCAP channel) of raw beam events."""
    events, rejects = read_beam_events(raw, tuple(beam_ids), epoch=epoch, path=path)
    return _decode_events(events, rejects, raw.source, path)


def _decode_events(
    events: pl.DataFrame, rejects: pl.DataFrame, source: str, path: Path | None, file: FileLines | None = None
) -> BeamDecode:
    out = decode_passes(events, source, file=file)  # with the file read: its rejects' text
    if out.rejects.height:
        fixed = out.rejects
        if path is not None and fixed["raw"].null_count() == fixed.height:  # not named by decode_passes
            lines = fixed["line"].to_list()
            text = file.texts(lines) if file is not None else raw_lines(path, lines)  # (the file read again)
            fixed = fixed.with_columns(pl.Series("raw", [text.get(i) for i in lines], dtype=pl.String))
        rejects = pl.concat([rejects, fixed.select(REJECTS.names())]).sort("line")
    return BeamDecode(out.events, out.crossings, out.aborted, out.unfinished, rejects)


def crossing_reach(site, beam_id: str) -> float:
    """How far (site units) from the beam's segment the centre of a body may be at the time of
    one of its crossings: a crossing is logged at its last edge, when the body has just cleared
    the far pair, so the centre is ``spacing / 2 + body_radius`` past the segment (and no
    further while any pair is blocked). Trackers that place a target at a crossing use this
    reach, never a constant of their own (:func:`onebit.core.sensing.body_radius`)."""
    return site.beam(beam_id).spacing / 2.0 + body_radius(site)
