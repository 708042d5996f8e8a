"""Raw logs as MCAP: one JSON channel per source, typed view channels, conversion to and from CSV.

A dataset's raw logs (``beams.csv``, ``crossings.csv``, ...) may arrive as one
``recording.mcap`` with one channel per source. The topic is ``"/" + <CSV stem>``, messages
are JSON objects with the CSV's columns (one message per row), ``log_time`` =
``publish_time`` = ``round(t * 1e9)`` ns when ``t`` is a non-negative finite number, the
Unix nanoseconds of an ISO stamp, else the message's 0-based index in its channel; each
channel has a JSON schema (``onebit.<stem>``). These raw channels are what round-trips.

Files are written with the ``mcap`` library: chunked (1 MiB), zstd-compressed, with chunk
and message indexes, statistics and a summary (``mcap info`` / ``rerun mcap info`` show them).
Beside the raw channels :func:`write_mcap` adds the typed view channels of
:mod:`onebit.readers.mcap_views` (Foxglove's ``SceneUpdate``, ``PointCloud`` and ``Log``
schemas, protobuf-encoded) so that Foxglove and ``rerun file.mcap`` draw the site, the sensors'
states, the truth and a run's tracks; the reader skips them (they are derived, counted in
``McapContents.views``).

MCAP from other tools: ROS 2 bags with one boolean per message (``std_msgs/msg/Bool`` or any
CDR message with a boolean field) become toggle rows through a small topic map
(:func:`load_topic_map`, a dataset's ``mcap_topics.toml``): topic -> sensor id, kind
(``motion`` | ``proximity``) and field. ``t`` is the message's log time in Unix seconds.

:func:`read_mcap` delivers each channel as all-string columns plus ``line`` and ``raw``, the
same shape the CSV readers produce (see :mod:`onebit.readers.rows`), so the same
validation applies to both. The reading lives in :mod:`onebit.readers.mcap_read` (its names
are importable from here too); this module writes and converts.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

import polars as pl

from onebit.core.errors import InputError
from onebit.core.site import load_site
from onebit.core.tables import REJECTS
from onebit.core.writers import atomic_path
from onebit.readers import mcap_views
from onebit.readers.mcap_read import (
    CHANNELS,
    MAGIC,
    TOGGLE_KINDS,
    McapContents,
    TopicMapping,
    load_topic_map,
    read_mcap,
)
from onebit.readers.mcap_views import ViewMessage
from onebit.readers.motion import TOGGLE_VALUES
from onebit.readers.timebase import iso_unix_us

#: Names of the MCAP raw logs: the writing and conversion here, the reading from :mod:`onebit.readers.mcap_read`.
__all__ = [
    "CHANNELS",
    "CHUNK_SIZE",
    "MAGIC",
    "TOGGLE_KINDS",
    "Conversion",
    "McapContents",
    "TopicMapping",
    "csv_folder_to_mcap",
    "load_topic_map",
    "mcap_to_csv_folder",
    "read_mcap",
    "tracks_for_views",
    "write_mcap",
]

#: Bytes of uncompressed messages per chunk.
CHUNK_SIZE = 1024 * 1024


_SCHEMA_PREFIX = "onebit."
_IGNORED_COLUMNS = ("line", "raw")


@dataclass(frozen=True)
class Conversion:
    """Result of a conversion: the files written and the rows that could not be carried over."""

    written: list[Path]
    rejects: pl.DataFrame = field(default_factory=lambda: pl.DataFrame(schema=REJECTS))


# --------------------------------------------------------------------------- atomic output


@contextmanager
def _atomic(path: Path) -> Iterator[IO[bytes]]:
    """A binary file handle on a temp file next to ``path``, flushed to disk and renamed over
    ``path`` on success (:func:`onebit.core.writers.atomic_path`)."""
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        yield fh
        fh.flush()
        os.fsync(fh.fileno())


# --------------------------------------------------------------------------- writing


def _json_type(dtype: pl.DataType) -> list[str]:
    if dtype == pl.Boolean:
        return ["boolean", "null"]
    if dtype.is_numeric():
        return ["number", "null"]
    return ["string", "null"]


def _log_time(df: pl.DataFrame) -> pl.Expr:
    """``log_time`` (ns) of each row: ``round(t * 1e9)`` for a non-negative finite number, the
    Unix ns of an ISO stamp, else the row's 0-based index."""
    if df.schema["t"] == pl.String:
        t = pl.col("t").str.strip_chars().cast(pl.Float64, strict=False)
        iso = iso_unix_us(pl.col("t")) * 1000
    else:
        t = pl.col("t").cast(pl.Float64, strict=False)
        iso = pl.lit(None, pl.Int64)
    ns = (t * 1e9).round(0)
    index = pl.int_range(pl.len(), dtype=pl.Int64)
    ok = ns.is_not_null() & ns.is_finite() & (ns >= 0) & (ns < 2**63)
    return (
        pl.when(ok)
        .then(ns.cast(pl.Int64, strict=False))
        .when(iso.is_not_null() & (iso >= 0))
        .then(iso)
        .otherwise(index)
    )


def _channel_messages(topic: str, df: pl.DataFrame) -> pl.DataFrame:
    """One row per message of ``topic``: ``log_time``, ``key`` (merge order), ``data`` (JSON)
    and the channel's columns as strings (for the views)."""
    columns = CHANNELS[topic]
    missing = [c for c in columns if c not in df.columns]
    extra = [c for c in df.columns if c not in columns and c not in _IGNORED_COLUMNS]
    if missing or extra:
        raise InputError(
            f"table for topic {topic} must have columns {list(columns)}; missing {missing}, unexpected {extra}"
        )
    df = df.select(columns)
    if df.height == 0:
        return pl.DataFrame(
            schema={"log_time": pl.Int64, "data": pl.String, **{c: pl.String for c in columns}, "key": pl.Int64}
        )
    return df.select(
        _log_time(df).alias("log_time"),
        pl.struct(columns).struct.json_encode().alias("data"),
        *(pl.col(c).cast(pl.String).str.strip_chars().alias(c) for c in columns),
    ).with_columns(pl.col("log_time").cum_max().alias("key"))


def _views(per_topic: dict[str, pl.DataFrame], site, tracks: pl.DataFrame | None) -> list[ViewMessage]:
    """The typed view messages (:mod:`onebit.readers.mcap_views`) of the raw channels."""
    out: list[ViewMessage] = []
    starts = [int(m["log_time"].min()) for m in per_topic.values() if m.height]
    if tracks is not None and tracks.height:
        starts.append(int(tracks["log_time"].min()))
    if site is not None:
        out += mcap_views.site_views(site, min(starts) if starts else 0)
    toggles = [
        per_topic[t].select(
            "log_time",
            "sensor",
            pl.col("value").str.to_lowercase().replace_strict(TOGGLE_VALUES, default=None).alias("on"),
        )
        for t in ("/motion", "/proximity")
        if t in per_topic
    ]
    if toggles:
        out += mcap_views.toggle_views(pl.concat(toggles).sort("log_time", maintain_order=True), site)
    if "/truth" in per_topic:
        truth = per_topic["/truth"].select(
            "log_time",
            pl.col("target").alias("id"),
            pl.col("x").cast(pl.Float64, strict=False),
            pl.col("y").cast(pl.Float64, strict=False),
        )
        out += mcap_views.position_views(truth.drop_nulls(), kind="truth", site=site)
    if tracks is not None and tracks.height:
        out += mcap_views.position_views(tracks.drop_nulls(["x", "y"]), kind="tracks", site=site)
    lines = []
    for topic, text in (
        ("/motion", pl.format("{} {}", "sensor", "value")),
        ("/proximity", pl.format("{} {}", "sensor", "value")),
        ("/crossings", pl.format("{} crossed {}", "beam", "direction")),
        ("/beams", pl.format("{} pair {} blocked={}", "beam", "pair", "blocked")),
    ):
        if topic in per_topic and per_topic[topic].height:
            lines.append(
                per_topic[topic].select(
                    "log_time", pl.lit(topic.lstrip("/")).alias("name"), text.fill_null("?").alias("text")
                )
            )
    if lines:
        out += mcap_views.event_views(pl.concat(lines).sort("log_time", maintain_order=True))
    return out


def tracks_for_views(tracks: pl.DataFrame, *, offset_s: float = 0.0) -> pl.DataFrame:
    """A run's ``tracks`` (TRACKS schema, ``t`` in run seconds) as view input: ``log_time`` =
    ``round((t + offset_s) * 1e9)`` (``offset_s``: the run's time origin in the logs' own
    seconds, so the tracks line up with the raw messages), ``id`` = ``tracker/track``."""
    return tracks.select(
        ((pl.col("t") + offset_s) * 1e9).round(0).cast(pl.Int64).alias("log_time"),
        pl.format("{}/{}", "tracker", "track").alias("id"),
        pl.col("x").cast(pl.Float64),
        pl.col("y").cast(pl.Float64),
    ).filter(pl.col("log_time") >= 0)


def write_mcap(
    path: str | Path,
    tables: dict[str, pl.DataFrame],
    *,
    site=None,
    views: bool = True,
    tracks: pl.DataFrame | None = None,
) -> None:
    """Write raw-log tables as one MCAP file, atomically.

    Parameters
    ----------
    path
        Output file; written to a temp file in the same folder and renamed over it.
    tables
        Topic (a key of :data:`CHANNELS`) -> frame with exactly that channel's columns (any
        dtypes; string columns stay JSON strings, numbers stay numbers, nulls become JSON
        ``null``). Columns named ``line`` / ``raw`` (from :func:`read_mcap`) are ignored.
    site
        The :class:`~onebit.core.site.Site` of the logs, for the site and sensor views
        (``None``: no site, no sensor spheres; the truth, tracks and event views are kept).
    views
        Add the typed view channels (:mod:`onebit.readers.mcap_views`); ``False`` writes
        the raw channels only.
    tracks
        Estimates to show (:func:`tracks_for_views`: ``log_time``, ``id``, ``x``, ``y``).

    Notes
    -----
    One JSON schema and one channel per topic, then every message merged across channels in
    time order (each channel's own row order is kept, so a row out of order in the input is
    still out of order in the file); the view messages are merged in by log time. Chunked
    (:data:`CHUNK_SIZE`), zstd, with chunk and message indexes and a summary. The file is
    written to a temp file and renamed, so an interrupted write never leaves a half file.

    Raises
    ------
    InputError
        An unknown topic or a frame whose columns do not match the channel.
    """
    from mcap.writer import CompressionType, Writer
    from mcap_protobuf.schema import register_schema

    path = Path(path)
    unknown = [t for t in tables if t not in CHANNELS]
    if unknown:
        raise InputError(f"unknown topic(s) {unknown}; known: {list(CHANNELS)}", file=path)
    per_topic = {topic: _channel_messages(topic, df) for topic, df in tables.items()}
    view_msgs = _views(per_topic, site, tracks) if views else []
    with _atomic(path) as fh:
        writer = Writer(fh, chunk_size=CHUNK_SIZE, compression=CompressionType.ZSTD, use_chunking=True)
        writer.start(profile="", library="onebit")
        ids = _register_raw_channels(writer, tables)
        view_ids = _register_view_channels(writer, view_msgs, register_schema)
        frames = [
            m.select("log_time", "key", "data").with_columns(
                pl.lit(ids[topic], pl.Int64).alias("channel"),
                pl.lit(order, pl.Int64).alias("order"),
                pl.int_range(pl.len(), dtype=pl.Int64).alias("seq"),
            )
            for order, (topic, m) in enumerate(per_topic.items())
        ]
        raw = pl.concat(frames).sort(["key", "order", "seq"], maintain_order=True) if frames else None
        view_seq: dict[str, int] = {}

        def write_views_until(limit: int | None, start: int) -> int:
            """Write view messages from ``start`` with log_time <= limit (all when None)."""
            i = start
            while i < len(view_msgs) and (limit is None or view_msgs[i].log_time <= limit):
                m = view_msgs[i]
                seq = view_seq[m.topic] = view_seq.get(m.topic, -1) + 1
                writer.add_message(
                    channel_id=view_ids[m.topic],
                    log_time=m.log_time,
                    publish_time=m.log_time,
                    sequence=seq & 0xFFFFFFFF,
                    data=m.message.SerializeToString(),
                )
                i += 1
            return i

        view_msgs.sort(key=lambda m: m.log_time)  # stable: each view channel keeps its order
        done = 0
        if raw is not None:
            for channel, key, log_time, seq, data in zip(
                raw["channel"].to_list(),
                raw["key"].to_list(),
                raw["log_time"].to_list(),
                raw["seq"].to_list(),
                raw["data"].to_list(),
                strict=True,
            ):
                done = write_views_until(key - 1, done)
                writer.add_message(
                    channel_id=channel,
                    log_time=log_time,
                    publish_time=log_time,
                    sequence=seq & 0xFFFFFFFF,
                    data=data.encode(),
                )
        write_views_until(None, done)
        writer.finish()


def _register_raw_channels(writer, tables: dict[str, pl.DataFrame]) -> dict[str, int]:
    """One JSON schema and one channel per raw topic, in the order of ``tables``: topic -> channel id."""
    ids: dict[str, int] = {}
    for topic, df in tables.items():
        columns = CHANNELS[topic]
        schema = {
            "type": "object",
            "title": topic.lstrip("/"),
            "properties": {c: {"type": _json_type(df.schema[c])} for c in columns},
            "required": list(columns),
        }
        sid = writer.register_schema(
            name=_SCHEMA_PREFIX + topic.lstrip("/"),
            encoding="jsonschema",
            data=json.dumps(schema).encode(),
        )
        ids[topic] = writer.register_channel(topic=topic, message_encoding="json", schema_id=sid)
    return ids


def _register_view_channels(writer, view_msgs: list, register_schema) -> dict[str, int]:
    """One protobuf channel per view topic, in order of first message (one schema per message
    class): topic -> channel id."""
    view_ids: dict[str, int] = {}
    schema_ids: dict[type, int] = {}
    for m in view_msgs:
        if m.topic not in view_ids:
            cls = type(m.message)
            if cls not in schema_ids:
                schema_ids[cls] = register_schema(writer, cls)
            view_ids[m.topic] = writer.register_channel(
                topic=m.topic, message_encoding="protobuf", schema_id=schema_ids[cls]
            )
    return view_ids


# --------------------------------------------------------------------------- conversion


def _topic_of(path: Path) -> str | None:
    topic = "/" + path.stem
    return topic if topic in CHANNELS and path.suffix.lower() in (".csv", ".parquet") else None


def _read_table_as_strings(path: Path) -> pl.DataFrame:
    """A CSV (every column String) or Parquet (every column cast to String) raw-log file."""
    topic = _topic_of(path)
    assert topic is not None
    try:
        if path.suffix.lower() == ".csv":
            try:
                df = pl.read_csv(path, infer_schema=False)
            except pl.exceptions.NoDataError:
                df = pl.DataFrame(schema={c: pl.String for c in CHANNELS[topic]})
        else:
            df = pl.read_parquet(path)
            df = df.with_columns(pl.all().cast(pl.String))
    except (pl.exceptions.PolarsError, OSError) as exc:
        raise InputError(f"cannot read: {exc}", file=path) from None
    df = df.rename({c: c.strip() for c in df.columns})
    wanted = CHANNELS[topic]
    missing = [c for c in wanted if c not in df.columns]
    extra = [c for c in df.columns if c not in wanted]
    if missing:
        raise InputError(f"missing column(s) {missing}; the header has {df.columns}", file=path, line=1)
    if extra:
        raise InputError(f"unexpected column(s) {extra}; expected {list(wanted)}", file=path, line=1)
    return df.select(wanted)


def csv_folder_to_mcap(
    folder_or_file: str | Path,
    out_path: str | Path,
    *,
    views: bool = True,
    site=None,
    tracks: pl.DataFrame | None = None,
) -> Conversion:
    """Convert raw-log CSV/Parquet files to one MCAP file (:func:`write_mcap`).

    Parameters
    ----------
    folder_or_file
        A dataset folder (every known ``<stem>.csv`` / ``<stem>.parquet`` in it is taken) or
        one such file.
    out_path
        The ``.mcap`` to write (atomically).
    views
        Add the typed view channels (:mod:`onebit.readers.mcap_views`).
    site
        The site for the views; ``None`` = the folder's ``site.toml`` when there is one.
    tracks
        Estimates for the ``/foxglove/tracks`` and ``/points/tracks`` views
        (:func:`tracks_for_views`).

    Returns
    -------
    Conversion
        ``written = [out_path]``; ``rejects`` is empty (malformed files raise instead).

    Raises
    ------
    InputError
        No known raw-log file, the same source both as CSV and Parquet, a file that cannot be
        parsed (e.g. a row with too many fields) or whose columns do not match its channel.
    """
    src = Path(folder_or_file)
    out_path = Path(out_path)
    if src.is_dir():
        files = sorted(p for p in src.iterdir() if p.is_file() and _topic_of(p) is not None)
    elif src.is_file():
        if _topic_of(src) is None:
            raise InputError(
                f"not a known raw log; expected one of {[t.lstrip('/') + '.csv' for t in CHANNELS]} (or .parquet)",
                file=src,
            )
        files = [src]
    else:
        raise InputError("no such file or folder", file=src)
    by_topic: dict[str, Path] = {}
    for p in files:
        topic = _topic_of(p)
        assert topic is not None
        if topic in by_topic:
            raise InputError(f"both {by_topic[topic].name} and {p.name} hold {topic}; keep one", file=src)
        by_topic[topic] = p
    if not by_topic:
        raise InputError("no raw-log CSV or Parquet files found", file=src)
    tables = {topic: _read_table_as_strings(by_topic[topic]) for topic in CHANNELS if topic in by_topic}
    folder = src if src.is_dir() else src.parent
    if site is None and views and (folder / "site.toml").is_file():
        site = load_site(folder / "site.toml")
    write_mcap(out_path, tables, site=site, views=views, tracks=tracks)
    return Conversion(written=[out_path])


def mcap_to_csv_folder(
    mcap_path: str | Path, out_dir: str | Path, *, topic_map: dict[str, TopicMapping] | None = None
) -> Conversion:
    """Write each raw-log channel of an MCAP file to ``<out_dir>/<stem>.csv``.

    Parameters
    ----------
    mcap_path
        The ``.mcap`` to read (see :func:`read_mcap`; a truncated file converts what it holds).
    topic_map
        Foreign boolean topics -> sensors (:func:`load_topic_map`), passed to :func:`read_mcap`.
    out_dir
        Folder to write into (created if needed); each CSV is written atomically with the
        columns in :data:`CHANNELS` order, nulls as empty fields.

    Returns
    -------
    Conversion
        The CSV paths written and the reader's rejects (messages that could not be carried
        over, and the truncation if any) for the caller to report.
    """
    contents = read_mcap(mcap_path, topic_map=topic_map)
    out_dir = Path(out_dir)
    written = []
    for topic in CHANNELS:
        if topic not in contents.channels:
            continue
        target = out_dir / (topic.lstrip("/") + ".csv")
        with _atomic(target) as fh:
            contents.channels[topic].select(CHANNELS[topic]).write_csv(fh)
        written.append(target)
    return Conversion(written=written, rejects=contents.rejects)
