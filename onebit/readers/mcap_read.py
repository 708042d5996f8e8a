"""Reading raw logs from MCAP (:mod:`onebit.readers.mcap_io`, module docstring): the raw-log
channels (:data:`CHANNELS`), the topic map of other tools' boolean topics
(:func:`load_topic_map`) and :func:`read_mcap`, which streams a file's records and keeps
everything before a cut.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

import polars as pl

from onebit.core.config import load_toml
from onebit.core.errors import InputError, bounded
from onebit.core.tables import REJECTS
from onebit.readers.mcap_views import VIEW_TOPICS

#: Topic -> column names of each raw-log channel (topic = "/" + the CSV file's stem).
CHANNELS: dict[str, tuple[str, ...]] = {
    "/beams": ("t", "beam", "pair", "blocked"),
    "/crossings": ("t", "beam", "direction"),
    "/truth": ("t", "target", "x", "y"),
    "/truth_crossings": ("t", "beam", "direction", "target", "dropped"),  # dropped: simulator flag 0|1
    "/motion": ("t", "sensor", "value"),
    "/proximity": ("t", "sensor", "value"),
    "/frames": ("t", "active"),  # a frame-sampled log, list layout (onebit.readers.frames)
}


MAGIC = b"\x89MCAP0\r\n"


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
    views
        Topic -> messages skipped because they are derived views (:data:`VIEW_TOPICS`, or any
        protobuf channel): what the writer added for viewers, not input.
    unreadable
        True when the file is cut before any channel or message (inside its MCAP header, or in
        its first chunk): nothing of it could be read (its one reject says so, naming the file);
        the runner reports the file as unreadable, not the run as having nothing to do.
    """

    channels: dict[str, pl.DataFrame]
    rejects: pl.DataFrame
    truncated: bool
    views: dict[str, int] = field(default_factory=dict)
    unreadable: bool = False


#: Toggle channels a mapped ROS 2 topic may feed (``kind`` of :class:`TopicMapping`).
TOGGLE_KINDS = ("motion", "proximity")


@dataclass(frozen=True, kw_only=True)
class TopicMapping:
    """How the messages of one foreign topic become toggle rows (``mcap_topics.toml``).

    sensor : the sensor id the rows get (a sensor of ``site.toml``).
    kind : ``motion`` or ``proximity``: the channel the rows join.
    field : the message's boolean field (``std_msgs/msg/Bool``: ``data``).
    """

    sensor: str
    kind: str
    field: str = "data"

    def __post_init__(self) -> None:
        if not isinstance(self.sensor, str) or not self.sensor.strip():
            raise InputError(f"TopicMapping.sensor = {self.sensor!r}: must be a non-empty sensor id")
        if self.kind not in TOGGLE_KINDS:
            raise InputError(f"TopicMapping.kind = {self.kind!r}: must be one of {list(TOGGLE_KINDS)}")
        if not isinstance(self.field, str) or not self.field:
            raise InputError(f"TopicMapping.field = {self.field!r}: must be a field name")


def load_topic_map(path: str | Path) -> dict[str, TopicMapping]:
    """The ``[topics."<topic>"]`` tables of a ``mcap_topics.toml``::

        [topics."/hall/pir1"]
        sensor = "m1"          # sensor id in site.toml
        kind = "motion"        # motion | proximity
        field = "data"         # the boolean field (default: data, as in std_msgs/msg/Bool)

    Raises :class:`InputError` naming the file and the topic for anything else.
    """
    path = Path(path)
    data = load_toml(path, error=InputError)
    extra = [k for k in data if k != "topics"]
    if extra:
        raise InputError(f'unknown key(s) {extra}; expected only [topics."<topic>"] tables', file=path)
    topics = data.get("topics", {})
    if not isinstance(topics, dict):
        raise InputError("'topics' must be a table of [topics.\"<topic>\"] tables", file=path)
    out: dict[str, TopicMapping] = {}
    for topic, values in topics.items():
        if not isinstance(values, dict):
            raise InputError(f'[topics."{topic}"] must be a table with sensor, kind[, field]', file=path)
        unknown = [k for k in values if k not in ("sensor", "kind", "field")]
        if unknown:
            raise InputError(f'[topics."{topic}"]: unknown key(s) {unknown}; expected sensor, kind, field', file=path)
        try:
            out[topic] = TopicMapping(**values)
        except TypeError:
            raise InputError(f'[topics."{topic}"]: needs sensor and kind', file=path) from None
        except InputError as exc:
            raise InputError(f'[topics."{topic}"]: {exc}', file=path) from None
        if topic in CHANNELS:
            raise InputError(f'[topics."{topic}"]: {topic} is one of onebit\'s own channels', file=path)
    return out


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


@dataclass
class _McapRead:
    """What :func:`read_mcap` gathers while it walks the records of one file."""

    name: str  # the file's name: the source of its rejects
    topic_map: dict[str, TopicMapping]
    topics: dict[int, tuple[str, str]] = field(default_factory=dict)  # channel id -> (topic, encoding)
    channel_schema: dict[int, int] = field(default_factory=dict)
    schemas: dict[int, object] = field(default_factory=dict)
    decoders: dict[int, object] = field(default_factory=dict)
    views: dict[str, int] = field(default_factory=dict)
    unmapped: dict[str, list] = field(default_factory=dict)  # topic -> [count, encoding, schema name]
    cols: dict[str, dict[str, list]] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    rejects: list[tuple[str, int | None, str | None, str | None]] = field(default_factory=list)
    n_messages: int = 0

    def new_channel(self, topic: str) -> None:
        if topic in CHANNELS and topic not in self.cols:
            self.cols[topic] = {c: [] for c in (*CHANNELS[topic], "line", "raw")}


def read_mcap(path: str | Path, *, topic_map: dict[str, TopicMapping] | None = None) -> McapContents:
    """Read every raw-log channel of an MCAP file as string rows, keeping what precedes a cut.

    Parameters
    ----------
    path
        The ``.mcap`` file.
    topic_map
        Foreign topics -> :class:`TopicMapping` (:func:`load_topic_map`): their messages (ROS 2
        ``cdr``, decoded with ``mcap-ros2-support`` from the file's own message definition, or
        JSON) become rows of ``/motion`` / ``/proximity`` with ``t`` = log time in Unix
        seconds, ``value`` = the boolean field as ``1``/``0`` and ``raw`` = ``<topic>:
        <field>=<value>``; a message without that boolean field is a reject.

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
    or are on a JSON topic not in :data:`CHANNELS` (or on an undeclared channel id). A
    non-JSON channel that is neither a view nor mapped gives one reject for the channel,
    counting its messages (a ROS 2 bag's camera is not a one-bit log). View channels
    (:data:`VIEW_TOPICS`, protobuf) are skipped and counted in ``views``. JSON
    strings are kept as they are, numbers go through ``str()``, booleans/arrays/objects
    through ``json.dumps`` and ``null`` becomes a null.

    Raises
    ------
    InputError
        The file is missing, empty or not MCAP (bad magic).
    """
    path = Path(path)
    size = _check_magic(path)
    state = _McapRead(path.name, dict(topic_map or {}))
    with open(path, "rb") as fh:
        truncated, saw_header = _walk_records(fh, size, state)
    _unmapped_rejects(state)
    return McapContents(
        channels=_channel_frames(state),
        rejects=_rejects_frame(state.rejects),
        truncated=truncated,
        views=state.views,
        unreadable=truncated and not (state.n_messages or state.topics),
    )


def _walk_records(fh: IO[bytes], size: int, state: _McapRead) -> tuple[bool, bool]:
    """Read the records of an open MCAP file in order into ``state``; a decoding failure is the
    cut (one reject naming its byte offset). Returns ``(truncated, saw the header record)``."""
    from mcap.records import Channel, Footer, Header, Message, Schema
    from mcap.stream_reader import StreamReader

    records = StreamReader(fh, record_size_limit=max(size, 1)).records
    good_end = 0
    saw_footer = saw_header = False
    while True:
        try:
            record = next(records)
        except StopIteration:
            break
        except Exception as exc:  # noqa: BLE001 - any decoding failure past the magic is a cut
            state.rejects.append(
                (state.name, state.n_messages + 1, _cut_reason(exc, good_end, size, state, saw_header), None)
            )
            return True, saw_header
        good_end = fh.tell()
        if isinstance(record, Header):
            saw_header = True
        elif isinstance(record, Footer):
            saw_footer = True
        elif isinstance(record, Schema):
            state.schemas[record.id] = record
        elif isinstance(record, Channel):
            _on_channel(record, state)
        elif isinstance(record, Message):
            _on_message(record, state)
    if not saw_footer:  # pragma: no cover - StreamReader stops only at the footer
        reason = f"truncated: no footer (read {good_end} of {size} bytes)"
        state.rejects.append((state.name, state.n_messages + 1, reason, None))
        return True, saw_header
    return False, saw_header


def _cut_reason(exc: Exception, good_end: int, size: int, state: _McapRead, saw_header: bool) -> str:
    what = type(exc).__name__ + (f": {exc}" if str(exc) else "")
    if not saw_header:
        return f"unreadable: truncated in its MCAP header (the file has {size} bytes; {what})"
    return (
        f"truncated: file ends or breaks at byte {good_end} of {size} "
        f"after {state.n_messages} complete messages ({what})"
    )


def _on_channel(record, state: _McapRead) -> None:
    """A channel record: its topic and encoding, and the columns of a onebit channel (or of the
    channel a mapped foreign topic feeds)."""
    state.topics[record.id] = (record.topic, record.message_encoding)
    state.channel_schema[record.id] = record.schema_id
    state.new_channel(record.topic)
    mapping = state.topic_map.get(record.topic)
    if mapping is not None:
        state.new_channel("/" + mapping.kind)


def _on_message(record, state: _McapRead) -> None:
    """A message record: counted as a view, decoded through its topic mapping, counted on an
    unmapped binary topic, or read as a JSON row of a onebit channel (else a reject)."""
    state.n_messages += 1
    topic, encoding = state.topics.get(record.channel_id, (f"channel {record.channel_id}", "json"))
    if topic in VIEW_TOPICS or encoding.lower() == "protobuf":
        state.views[topic] = state.views.get(topic, 0) + 1
    elif topic in state.topic_map:
        _mapped_row(record, topic, encoding, state)
    elif encoding.lower() != "json" and topic not in CHANNELS:
        sch = state.schemas.get(state.channel_schema.get(record.channel_id, 0))
        entry = state.unmapped.setdefault(topic, [0, encoding, sch.name if sch is not None else ""])
        entry[0] += 1
    else:
        _json_row(record, topic, encoding, state)


def _mapped_row(record, topic: str, encoding: str, state: _McapRead) -> None:
    """A message of a mapped foreign topic: one toggle row of its ``/motion`` or ``/proximity``."""
    mapping = state.topic_map[topic]
    target = "/" + mapping.kind
    state.counts[topic] = state.counts.get(topic, 0) + 1
    schema = state.schemas.get(state.channel_schema.get(record.channel_id, 0))
    value, why = _mapped_value(record, encoding, mapping, schema, state.decoders)
    if why is not None:
        state.rejects.append((f"{state.name}:{topic}", state.counts[topic], why, bytes(record.data).hex()[:200]))
        return
    out = state.cols[target]
    line = state.counts[target] = state.counts.get(target, 0) + 1
    out["t"].append(f"{record.log_time / 1e9:.9f}")
    out["sensor"].append(mapping.sensor)
    out["value"].append("1" if value else "0")
    out["line"].append(line)
    out["raw"].append(f"{topic}: {mapping.field}={value}")


def _json_row(record, topic: str, encoding: str, state: _McapRead) -> None:
    """A message that should be a JSON object with exactly the fields of a onebit channel."""
    line = state.counts[topic] = state.counts.get(topic, 0) + 1
    text = bytes(record.data).decode("utf-8", errors="replace")
    source = f"{state.name}:{topic}"
    why = _json_problem(record, topic, encoding, state)
    if why is None:
        try:
            obj = json.loads(record.data)
        except (ValueError, UnicodeDecodeError) as exc:
            why = f"not valid JSON: {exc}"
        else:
            why = _fields_problem(obj, CHANNELS[topic])
    if why is not None:
        state.rejects.append((source, line, why, text))
        return
    out = state.cols[topic]
    for c in CHANNELS[topic]:
        out[c].append(_cell(obj[c]))
    out["line"].append(line)
    out["raw"].append(text)


def _json_problem(record, topic: str, encoding: str, state: _McapRead) -> str | None:
    """Why a message cannot be a row before its text is parsed: an unknown topic or channel,
    an encoding that is not JSON."""
    if topic not in CHANNELS:
        if record.channel_id in state.topics:
            return f"unknown topic {topic}"
        return f"message on undeclared channel id {record.channel_id}"
    if encoding.lower() != "json":
        return f"message encoding '{encoding}' is not json"
    return None


def _fields_problem(obj: object, wanted: tuple[str, ...]) -> str | None:
    """Why a parsed message is not a row of a channel with fields ``wanted``, else ``None``."""
    if not isinstance(obj, dict):
        return f"not a JSON object (a {type(obj).__name__})"
    missing = [c for c in wanted if c not in obj]
    extra = [k for k in obj if k not in wanted]
    parts = []
    if missing:
        parts.append("missing field(s) " + ", ".join(f"'{c}'" for c in missing))
    if extra:
        parts.append("unexpected field(s) " + ", ".join(f"'{k}'" for k in extra))
    return "; ".join(parts) or None


def _unmapped_rejects(state: _McapRead) -> None:
    """One reject per binary topic that is neither a view nor mapped, counting its messages."""
    for topic, (n, encoding, schema_name) in state.unmapped.items():
        state.rejects.append(
            (
                f"{state.name}:{topic}",
                None,
                f"{n} message(s) in encoding '{encoding}'{f' ({schema_name})' if schema_name else ''} on a topic that is not "
                "a onebit channel and not mapped: map a boolean topic to a sensor in mcap_topics.toml",
                None,
            )
        )


def _channel_frames(state: _McapRead) -> dict[str, pl.DataFrame]:
    return {
        topic: pl.DataFrame(
            data,
            schema={**{c: pl.String for c in CHANNELS[topic]}, "line": pl.Int64, "raw": pl.String},
        )
        for topic, data in state.cols.items()
    }


def _rejects_frame(rejects: list) -> pl.DataFrame:
    """The rejects, reasons and raw text quoted bounded, as every reader's."""
    rows = [
        (src, line, None if why is None else bounded(why), None if raw is None else bounded(raw))
        for src, line, why, raw in rejects
    ]
    return pl.DataFrame(rows, schema=REJECTS, orient="row")


def _mapped_value(
    record, encoding: str, mapping: TopicMapping, schema, decoders: dict
) -> tuple[bool | None, str | None]:
    """The boolean ``mapping.field`` of a mapped message, or ``(None, reason)``."""
    enc = encoding.lower()
    if enc == "cdr":
        if schema is None:
            return None, "cdr message without a schema (message definition) in the file"
        dec = decoders.get(schema.id)
        if dec is None:
            from mcap_ros2.decoder import DecoderFactory

            dec = decoders[schema.id] = DecoderFactory().decoder_for("cdr", schema)
            if dec is None:
                return None, f"schema {schema.name!r} ({schema.encoding}) cannot be decoded as ROS 2"
        try:
            obj = dec(bytes(record.data))
        except Exception as exc:  # noqa: BLE001 - any CDR decoding failure is this message's reject
            return None, f"not decodable as {schema.name}: {type(exc).__name__}: {exc}"
        value = getattr(obj, mapping.field, None)
    elif enc == "json":
        try:
            obj = json.loads(record.data)
        except (ValueError, UnicodeDecodeError) as exc:
            return None, f"not valid JSON: {exc}"
        value = obj.get(mapping.field) if isinstance(obj, dict) else None
    else:
        return None, f"message encoding '{encoding}' is not cdr or json"
    if not isinstance(value, bool):
        return None, f"field '{mapping.field}' is {type(value).__name__}, not a boolean"
    return value, None
