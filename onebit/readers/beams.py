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

from dataclasses import dataclass
from pathlib import Path

import polars as pl

from onebit.readers.rows import RawRows, make_rejects, parse_choice, parse_name, parse_time, read_csv_rows, type_rows
from onebit.core.tables import ABORTED, BEAM_EVENTS, CROSSINGS, REJECTS, conform
from onebit.readers.rows import raw_lines

BEAM_COLUMNS = ("t", "beam", "pair", "blocked")


@dataclass(frozen=True)
class BeamDecode:
    """Result of decoding a raw beam log."""

    events: pl.DataFrame  # accepted events (BEAM_EVENTS + line)
    crossings: pl.DataFrame  # CROSSINGS
    aborted: pl.DataFrame  # ABORTED: start-and-return passes
    unfinished: pl.DataFrame  # beam, t of the last edge of passes still open at the end
    rejects: pl.DataFrame  # REJECTS


def read_beam_events(raw: RawRows, beam_ids: tuple[str, ...], *, epoch: str | None = None, path: Path | None = None):
    """Type and check raw beam rows: ``t``, known ``beam``, ``pair`` in a|b, ``blocked`` in 0|1."""
    parsers = {
        "t": parse_time("t", epoch, raw.frame),
        "beam": parse_name("beam", beam_ids, "beam"),
        "pair": parse_choice("pair", {"a": "a", "b": "b", "A": "a", "B": "b"}, pl.String),
        "blocked": parse_choice("blocked", {"1": True, "0": False, "true": True, "false": False}, pl.Boolean),
    }
    return type_rows(raw, parsers, key=("t", "beam", "pair", "blocked"), path=path)


def decode_passes(events: pl.DataFrame, source: str = "beams.csv") -> BeamDecode:
    """Decode accepted beam events (``line``, t, beam, pair, blocked; sorted by t) into crossings.

    Edges that do not change their pair's state (blocked while already blocked, or clear
    while clear) cannot come from a body and are rejected with their line.
    """
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
            pl.when(pl.col("blocked") == prev).then(pl.lit("no state change after a rejected edge")).otherwise(None).alias("_reason")
        )
        more = ev.filter(pl.col("_reason").is_not_null())
        if more.height == 0:
            break
        bad = pl.concat([bad, more])
    rejects = make_rejects(bad.sort("line"), source, None)
    ev = ev.drop("_reason")

    state_a = pl.when(pl.col("pair") == "a").then(pl.col("blocked")).otherwise(None).forward_fill().over("beam").fill_null(False)
    state_b = pl.when(pl.col("pair") == "b").then(pl.col("blocked")).otherwise(None).forward_fill().over("beam").fill_null(False)
    ev = ev.with_columns(idle=~state_a & ~state_b)
    ev = ev.with_columns(passno=pl.col("idle").cast(pl.Int64).cum_sum().shift(1).fill_null(0).over("beam"))
    passes = ev.group_by(["beam", "passno"], maintain_order=True).agg(
        first=pl.col("pair").first(),
        last=pl.col("pair").last(),
        closed=pl.col("idle").last(),
        t=pl.col("t").last(),
    )
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
    unfinished = passes.filter(~pl.col("closed")).select("t", "beam")
    return BeamDecode(conform(ev, BEAM_EVENTS), crossings, aborted, unfinished, rejects)


def decode_beam_log(path: str | Path, beam_ids: tuple[str, ...], *, epoch: str | None = None) -> BeamDecode:
    """Read ``beams.csv`` and decode it: the whole raw-beam reader."""
    path = Path(path)
    raw = read_csv_rows(path, BEAM_COLUMNS)
    return decode_raw_beams(raw, beam_ids, epoch=epoch, path=path)


def decode_raw_beams(raw: RawRows, beam_ids, *, epoch=None, path: Path | None = None) -> BeamDecode:
    """Decode string rows (from CSV or an MCAP channel) of raw beam events."""
    events, rejects = read_beam_events(raw, tuple(beam_ids), epoch=epoch, path=path)
    out = decode_passes(events, raw.source)
    if out.rejects.height:
        fixed = out.rejects.join(events.select("line"), on="line", how="left")
        lines = fixed["line"].to_list()
        if path is not None:

            text = raw_lines(path, lines)
            fixed = fixed.with_columns(pl.Series("raw", [text.get(i) for i in lines], dtype=pl.String))
        rejects = pl.concat([rejects, fixed.select(REJECTS.names())]).sort("line")
    return BeamDecode(out.events, out.crossings, out.aborted, out.unfinished, rejects)
