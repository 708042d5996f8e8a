"""Raw logs as MCAP: one JSON channel per source, and conversion to and from CSV folders.

A dataset's raw logs (``beams.csv``, ``crossings.csv``, ...) may arrive as one
``recording.mcap`` with one channel per source. The topic is ``"/" + <CSV stem>``, messages
are JSON objects with the CSV's columns (one message per row), ``log_time`` =
``publish_time`` = ``round(t * 1e9)`` ns when ``t`` is a non-negative finite number (else
the message's 0-based index in its channel), and each channel has a JSON schema.

:func:`read_mcap` delivers each channel as all-string columns plus ``line`` and ``raw``, the
same shape the CSV readers produce (see :mod:`onebit.readers.rows`), so the same
validation applies to both.
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
from onebit.core.writers import atomic_path
from onebit.core.tables import REJECTS

#: Topic -> column names of each raw-log channel (topic = "/" + the CSV file's stem).
CHANNELS: dict[str, tuple[str, ...]] = {
    "/beams": ("t", "beam", "pair", "blocked"),
    "/crossings": ("t", "beam", "direction"),
    "/truth": ("t", "target", "x", "y"),
    "/truth_crossings": ("t", "beam", "direction", "target", "dropped"),  # dropped: simulator flag 0|1
    "/motion": ("t", "sensor", "value"),
    "/proximity": ("t", "sensor", "value"),
}

MAGIC = b"\x89MCAP0\r\n"
_SCHEMA_PREFIX = "onebit."
_IGNORED_COLUMNS = ("line", "raw")


@dataclass(frozen=True)
class McapContents:
    """What :func:`read_mcap` found.

    Attributes
    ----------
    channels
        Topic -> frame with the channel's columns (``pl.String``), ``line: Int64`` (1-based
        index of the message in its channel) and ``raw: String`` (the message's JSON text).
        Every known topic that has a channel record in the file is present, possibly empty.
    rejects
        Messages not accepted, in the :data:`onebit.core.tables.REJECTS` schema.
    truncated
        True when the file ended before its footer (the data before the cut is kept).
    """

    channels: dict[str, pl.DataFrame]
    rejects: pl.DataFrame
    truncated: bool


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


def _channel_messages(topic: str, df: pl.DataFrame) -> pl.DataFrame:
    """One row per message of ``topic``: ``log_time``, ``key`` (merge order), ``data`` (JSON)."""
    columns = CHANNELS[topic]
    missing = [c for c in columns if c not in df.columns]
    extra = [c for c in df.columns if c not in columns and c not in _IGNORED_COLUMNS]
    if missing or extra:
        raise InputError(
            f"table for topic {topic} must have columns {list(columns)}; "
            f"missing {missing}, unexpected {extra}"
        )
    df = df.select(columns)
    if df.height == 0:
        return pl.DataFrame(schema={"log_time": pl.Int64, "key": pl.Int64, "data": pl.String})
    if df.schema["t"] == pl.String:
        t = pl.col("t").str.strip_chars().cast(pl.Float64, strict=False)
    else:
        t = pl.col("t").cast(pl.Float64, strict=False)
    ns = (t * 1e9).round(0)
    index = pl.int_range(pl.len(), dtype=pl.Int64)
    ok = ns.is_not_null() & ns.is_finite() & (ns >= 0) & (ns < 2**63)
    log_time = pl.when(ok).then(ns.cast(pl.Int64, strict=False)).otherwise(index)
    return df.select(
        log_time.alias("log_time"),
        pl.struct(columns).struct.json_encode().alias("data"),
    ).with_columns(pl.col("log_time").cum_max().alias("key"))


def write_mcap(path: str | Path, tables: dict[str, pl.DataFrame]) -> None:
    """Write raw-log tables as one MCAP file, atomically.

    Parameters
    ----------
    path
        Output file; written to a temp file in the same folder and renamed over it.
    tables
        Topic (a key of :data:`CHANNELS`) -> frame with exactly that channel's columns (any
        dtypes; string columns stay JSON strings, numbers stay numbers, nulls become JSON
        ``null``). Columns named ``line`` / ``raw`` (from :func:`read_mcap`) are ignored.

    Notes
    -----
    One JSON schema and one channel per topic, then every message merged across channels in
    time order (each channel's own row order is kept, so a row out of order in the input is
    still out of order in the file). Messages are written unchunked and uncompressed, so a
    file cut short loses at most the message being written.

    Raises
    ------
    InputError
        An unknown topic or a frame whose columns do not match the channel.
    """
    from mcap.writer import CompressionType, Writer

    path = Path(path)
    unknown = [t for t in tables if t not in CHANNELS]
    if unknown:
        raise InputError(f"unknown topic(s) {unknown}; known: {list(CHANNELS)}", file=path)
    per_topic = {topic: _channel_messages(topic, df) for topic, df in tables.items()}
    with _atomic(path) as fh:
        writer = Writer(fh, compression=CompressionType.NONE, use_chunking=False)
        writer.start(profile="", library="onebit")
        ids: dict[str, int] = {}
        for order, (topic, df) in enumerate(tables.items()):
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
        frames = [
            m.with_columns(
                pl.lit(ids[topic], pl.Int64).alias("channel"),
                pl.lit(order, pl.Int64).alias("order"),
                pl.int_range(pl.len(), dtype=pl.Int64).alias("seq"),
            )
            for order, (topic, m) in enumerate(per_topic.items())
        ]
        if frames:
            merged = pl.concat(frames).sort(["key", "order", "seq"], maintain_order=True)
            for channel, log_time, seq, data in zip(
                merged["channel"].to_list(),
                merged["log_time"].to_list(),
                merged["seq"].to_list(),
                merged["data"].to_list(),
                strict=True,
            ):
                writer.add_message(
                    channel_id=channel,
                    log_time=log_time,
                    publish_time=log_time,
                    sequence=seq & 0xFFFFFFFF,
                    data=data.encode(),
                )
        writer.finish()


# --------------------------------------------------------------------------- reading


def _cell(value: object) -> str | None:
    """A JSON value as the string a CSV field would hold (``null`` -> None)."""
    if value is None:
        return None
    if isinstance(value, str):
        return value
    if isinstance(value, bool) or isinstance(value, (dict, list)):
        return json.dumps(value)
    return str(value)


def _check_magic(path: Path) -> int:
    """Return the file size; raise :class:`InputError` unless it starts with the MCAP magic."""
    try:
        size = path.stat().st_size
        with open(path, "rb") as fh:
            head = fh.read(len(MAGIC))
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", file=path) from None
    if not head:
        raise InputError("empty file, not an MCAP recording", file=path)
    if head != MAGIC[: len(head)]:
        raise InputError(f"not an MCAP file (bad magic {head[:8]!r})", file=path)
    return size


def read_mcap(path: str | Path) -> McapContents:
    """Read every raw-log channel of an MCAP file as string rows, keeping what precedes a cut.

    Parameters
    ----------
    path
        The ``.mcap`` file.

    Returns
    -------
    McapContents
        ``channels`` (topic -> String columns + ``line`` + ``raw``), ``rejects`` and
        ``truncated``.

    Notes
    -----
    The file is read sequentially with :class:`mcap.stream_reader.StreamReader`, so a file
    cut short still yields every complete record before the cut (for chunked files written by
    other tools: every complete chunk); the cut becomes one reject with source = the file
    name, line = messages read + 1 and a reason naming the byte offset. This is a Python loop
    over messages: MCAP decoding is per record, and so is ``json.loads``; the per-channel
    columns are collected as lists and turned into frames once at the end.

    Messages go to ``rejects`` (source ``"<file>:<topic>"``, line = index in the channel,
    raw = the text) when they are not UTF-8 JSON objects, lack a field of the channel,
    carry a field it does not have, are on a channel whose message encoding is not JSON,
    or are on a topic not in :data:`CHANNELS` (or on an undeclared channel id). JSON
    strings are kept as they are, numbers go through ``str()``, booleans/arrays/objects
    through ``json.dumps`` and ``null`` becomes a null.

    Raises
    ------
    InputError
        The file is missing, empty or not MCAP (bad magic).
    """
    from mcap.stream_reader import StreamReader
    from mcap.records import Channel, Footer, Message

    path = Path(path)
    size = _check_magic(path)
    name = path.name

    topics: dict[int, tuple[str, str]] = {}  # channel id -> (topic, message encoding)
    cols: dict[str, dict[str, list]] = {}
    counts: dict[str, int] = {}
    rejects: list[tuple[str, int | None, str, str | None]] = []
    n_messages = 0
    truncated = False

    def new_channel(topic: str) -> None:
        if topic in CHANNELS and topic not in cols:
            cols[topic] = {c: [] for c in (*CHANNELS[topic], "line", "raw")}

    with open(path, "rb") as fh:
        records = StreamReader(fh, record_size_limit=max(size, 1)).records
        good_end = 0
        saw_footer = False
        while True:
            try:
                record = next(records)
            except StopIteration:
                break
            except Exception as exc:  # noqa: BLE001 - any decoding failure past the magic is a cut
                truncated = True
                what = type(exc).__name__ + (f": {exc}" if str(exc) else "")
                rejects.append(
                    (
                        name,
                        n_messages + 1,
                        f"truncated: file ends or breaks at byte {good_end} of {size} "
                        f"after {n_messages} complete messages ({what})",
                        None,
                    )
                )
                break
            good_end = fh.tell()
            if isinstance(record, Footer):
                saw_footer = True
            elif isinstance(record, Channel):
                topics[record.id] = (record.topic, record.message_encoding)
                new_channel(record.topic)
            elif isinstance(record, Message):
                n_messages += 1
                topic, encoding = topics.get(record.channel_id, (f"channel {record.channel_id}", "json"))
                line = counts[topic] = counts.get(topic, 0) + 1
                text = bytes(record.data).decode("utf-8", errors="replace")
                source = f"{name}:{topic}"
                if topic not in CHANNELS:
                    why = (
                        f"unknown topic {topic}"
                        if record.channel_id in topics
                        else f"message on undeclared channel id {record.channel_id}"
                    )
                    rejects.append((source, line, why, text))
                    continue
                if encoding.lower() != "json":
                    rejects.append((source, line, f"message encoding '{encoding}' is not json", text))
                    continue
                try:
                    obj = json.loads(record.data)
                except (ValueError, UnicodeDecodeError) as exc:
                    rejects.append((source, line, f"not valid JSON: {exc}", text))
                    continue
                if not isinstance(obj, dict):
                    rejects.append((source, line, f"not a JSON object (a {type(obj).__name__})", text))
                    continue
                wanted = CHANNELS[topic]
                missing = [c for c in wanted if c not in obj]
                extra = [k for k in obj if k not in wanted]
                if missing or extra:
                    parts = []
                    if missing:
                        parts.append("missing field(s) " + ", ".join(f"'{c}'" for c in missing))
                    if extra:
                        parts.append("unexpected field(s) " + ", ".join(f"'{k}'" for k in extra))
                    rejects.append((source, line, "; ".join(parts), text))
                    continue
                out = cols[topic]
                for c in wanted:
                    out[c].append(_cell(obj[c]))
                out["line"].append(line)
                out["raw"].append(text)
        if not truncated and not saw_footer:  # pragma: no cover - StreamReader stops only at the footer
            truncated = True
            rejects.append((name, n_messages + 1, f"truncated: no footer (read {good_end} of {size} bytes)", None))

    channels = {
        topic: pl.DataFrame(
            data,
            schema={**{c: pl.String for c in CHANNELS[topic]}, "line": pl.Int64, "raw": pl.String},
        )
        for topic, data in cols.items()
    }
    rejects_df = pl.DataFrame(rejects, schema=REJECTS, orient="row")
    return McapContents(channels=channels, rejects=rejects_df, truncated=truncated)


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


def csv_folder_to_mcap(folder_or_file: str | Path, out_path: str | Path) -> Conversion:
    """Convert raw-log CSV/Parquet files to one MCAP file.

    Parameters
    ----------
    folder_or_file
        A dataset folder (every known ``<stem>.csv`` / ``<stem>.parquet`` in it is taken) or
        one such file.
    out_path
        The ``.mcap`` to write (atomically).

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
                f"not a known raw log; expected one of "
                f"{[t.lstrip('/') + '.csv' for t in CHANNELS]} (or .parquet)",
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
    write_mcap(out_path, tables)
    return Conversion(written=[out_path])


def mcap_to_csv_folder(mcap_path: str | Path, out_dir: str | Path) -> Conversion:
    """Write each raw-log channel of an MCAP file to ``<out_dir>/<stem>.csv``.

    Parameters
    ----------
    mcap_path
        The ``.mcap`` to read (see :func:`read_mcap`; a truncated file converts what it holds).
    out_dir
        Folder to write into (created if needed); each CSV is written atomically with the
        columns in :data:`CHANNELS` order, nulls as empty fields.

    Returns
    -------
    Conversion
        The CSV paths written and the reader's rejects (messages that could not be carried
        over, and the truncation if any) for the caller to report.
    """
    contents = read_mcap(mcap_path)
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
