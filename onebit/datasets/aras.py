"""ARAS homes (Alemdar, Ertan, Incel, Ersoy, "ARAS human activity datasets in multiple homes with
multiple residents", PervasiveHealth 2013, doi:10.4108/icst.pervasivehealth.2013.252120) ->
an onebit dataset folder.

``onebit import aras HOUSE_FOLDER DATASET [--days A-B]`` (:func:`import_aras`).

The input. A house folder holds ``DAY_1.txt`` ... ``DAY_30.txt`` and a ``README``. Each day
file has one line per second (86 400 lines, 00:00:00 to 23:59:59): the binary levels of the
house's sensors (20 in both published houses), then each resident's activity id (1-27; ``2`` =
Going Out, ``11`` = Sleeping, ``16`` = Napping), space separated. The README's table ``Column /
Sensor ID / Sensor Type / Place`` names the sensor columns; its ``ID ACTIVITY`` table names
the activities.

What is written (every file atomically)::

    site.toml        the person sensors as [[motion_sensors]] of their type, every type a
                     level sensor ([sensor_types.<type>] signal = "level": a force sensor held
                     on is someone sitting); the house door contact the entry/exit node;
                     positions SCHEMATIC (see below); the sensor graph; epoch
    motion.csv       t, sensor, value (1/0): every level change of a person sensor, and the
                     levels held at the first imported second -- a few thousand rows a day,
                     not 1.7 M per-second readings
    other.csv        t, sensor, kind, value: the same for sensors that say nothing of people
                     (temperature): kept, never given to a tracker
    truth_count.csv  t, end, count: people home (residents not Going Out) as intervals
    annotations.csv  t, end, resident, activity, name: each resident's activity intervals
    truth_events.csv t, sensor, residents: the person-sensor ON edges whose resident is known
                     by the rule below
    rejects.csv      file, line, reason, raw text of every line not used (when any)
    import.toml      what was read, written and rejected, the rules, the time line
    run.toml         [run] trackers = ["residents"]: what a plain ``onebit run`` runs (the
                     slot HMMs cost minutes per day of a home; --trackers overrides it)

Time line. ``t`` is seconds since ``epoch`` = ``2000-01-01T00:00:00`` (a notional date: ARAS
publishes no calendar dates). Day ``N`` starts ``(N - 1) x 86 400`` s after it, so every import
of a house shares one time line and the time of day is ``t mod 86 400`` (the ``day`` clock of a
known-residents profile reads it from the epoch).

Truth of identity per event (``truth_events.csv``). ARAS labels activities, not sensor events.
An ON edge of a person sensor at second ``t`` goes to resident ``r`` when, at ``t``, the
other resident is Going Out, Sleeping or Napping and ``r`` is none of these (only ``r`` can
have caused it); every other event stays unlabelled (both awake and home: either could have;
nobody awake: a sensor's own noise, or a sleeper turning over).

Positions. The paper's layout figure is not machine readable here; the sensors are placed
SCHEMATICALLY: each sensor's room is read from its README place (kitchen, bathroom, bedroom,
living room, hall: :data:`ROOM_WORDS`), rooms are boxes of a fixed flat plan
(:data:`ROOMS`), sensors are spread on a circle inside their room. Distances between rooms are
right in order (the hall joins them), not in metres. ``site.toml`` says so in its header.

Bad input. A line that does not hold the house's sensor columns plus two activity ids, a level
that is not 0/1 or an activity outside 1-27 is rejected (``rejects.csv``: file, line, reason,
text); its second keeps the levels and activities of the second before it. A day file shorter
than 86 400 lines is counted (``short_days``) and its missing seconds have no data (the day's
truth ends at its last line); lines beyond 86 400 are rejected.
"""

from __future__ import annotations

import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.errors import InputError
from onebit.core.site import site_from_dict
from onebit.core.tables import REJECTS
from onebit.core.writers import to_toml, write_csv, write_text
from onebit.datasets.importers import _v

#: The notional date of day 1's midnight.
EPOCH = "2000-01-01T00:00:00"
DAY_S = 86_400
#: Activity ids of ARAS (both houses).
GOING_OUT, SLEEPING, NAPPING = 2, 11, 16
N_ACTIVITIES = 27
#: Sensor types that say nothing of people (their levels go to other.csv).
NON_PERSON_TYPES = ("temperature",)

#: Room of a README place, by the first word group found in it (lower case).
ROOM_WORDS = (
    ("house door", "hall"),
    ("hall", "hall"),
    ("bathroom", "bathroom"),
    ("shower", "bathroom"),
    ("water closet", "bathroom"),
    ("tap", "bathroom"),
    ("kitchen", "kitchen"),
    ("fridge", "kitchen"),
    ("cupboard", "kitchen"),
    ("bed", "bedroom"),
    ("wardrobe", "bedroom"),
    ("closet", "bedroom"),
    ("couch", "living"),
    ("tv", "living"),
    ("armchair", "living"),
    ("chair", "living"),
)
#: The schematic flat (metres): room -> (x0, y0, x1, y1); the hall touches every room.
ROOMS = {
    "hall": (0.0, 3.0, 3.0, 6.0),
    "living": (3.0, 3.0, 8.0, 9.0),
    "kitchen": (3.0, 0.0, 8.0, 3.0),
    "bedroom": (-5.0, 3.0, 0.0, 9.0),
    "bathroom": (0.0, 0.0, 3.0, 3.0),
}
#: Rooms joined through a doorway (besides the hall, which joins all).
ADJACENT = {("living", "kitchen")}

DEFAULT_ACTIVITIES = {
    1: "Other",
    2: "Going Out",
    3: "Preparing Breakfast",
    4: "Having Breakfast",
    5: "Preparing Lunch",
    6: "Having Lunch",
    7: "Preparing Dinner",
    8: "Having Dinner",
    9: "Washing Dishes",
    10: "Having Snack",
    11: "Sleeping",
    12: "Watching TV",
    13: "Studying",
    14: "Having Shower",
    15: "Toileting",
    16: "Napping",
    17: "Using Internet",
    18: "Reading Book",
    19: "Laundry",
    20: "Shaving",
    21: "Brushing Teeth",
    22: "Talking on the Phone",
    23: "Listening to Music",
    24: "Cleaning",
    25: "Having Conversation",
    26: "Having Guest",
    27: "Changing Clothes",
}


@dataclass(frozen=True)
class ArasSensor:
    """One sensor column of a house: its README id, type, place, and the room read from it."""

    column: int
    id: str
    type: str
    place: str

    @property
    def room(self) -> str:
        p = self.place.lower()
        for word, room in ROOM_WORDS:
            if word in p:
                return room
        return "living"

    @property
    def person(self) -> bool:
        return self.type not in NON_PERSON_TYPES

    @property
    def door(self) -> bool:
        return self.type == "contact" and "house door" in self.place.lower()


@dataclass(frozen=True)
class ArasHouse:
    sensors: tuple[ArasSensor, ...]
    activities: dict[int, str]
    source: str


_SENSOR_ROW = re.compile(r"^\s*(\d+)\s+(\S+)\s+(.+?)\s{2,}(\S.*?)\s*$")


def read_readme(path: str | Path) -> ArasHouse:
    """The sensor columns and activity names of a house's README (module docstring)."""
    path = Path(path)
    if not path.is_file():
        raise InputError("no README beside the day files: it names the sensor columns", file=path)
    text = path.read_text(errors="replace").replace("\t", "    ")
    sensors, acts, section = [], {}, None
    for line in text.splitlines():
        low = line.lower()
        if "sensor explanations" in low:
            section = "sensors"
            continue
        if "activity explanations" in low:
            section = "activities"
            continue
        if section == "sensors":
            m = _SENSOR_ROW.match(line)
            if m and m.group(1).isdigit():
                col, sid, typ, place = int(m.group(1)), m.group(2), m.group(3).strip(), m.group(4).strip()
                sensors.append(ArasSensor(col, sid, _type_name(typ), place))
        elif section == "activities":
            m = re.match(r"^\s*(\d+)\s+(\S.*?)\s*$", line)
            if m:
                acts[int(m.group(1))] = m.group(2)
    if not sensors:
        raise InputError("no sensor table (Column, Sensor ID, Sensor Type, Place) found", file=path)
    cols = [s.column for s in sensors]
    if cols != list(range(1, len(cols) + 1)):
        raise InputError(f"sensor columns {cols}: expected 1..{len(cols)} in order", file=path)
    if len({s.id for s in sensors}) != len(sensors):
        raise InputError("a sensor id is listed twice", file=path)
    return ArasHouse(tuple(sensors), acts or dict(DEFAULT_ACTIVITIES), str(path))


def _type_name(typ: str) -> str:
    """``"Contact Sensor"`` -> ``"contact"``, ``"Sonar Distance"`` -> ``"sonar"``, ``"IR"`` -> ``"ir"``."""
    t = typ.lower().replace("sensor", "").strip()
    for word in ("photocell", "contact", "force", "pressure", "sonar", "distance", "temperature", "ir"):
        if t.startswith(word):
            return word
    return re.sub(r"\W+", "_", t) or "binary"


def parse_days(text: str | None) -> tuple[int, int] | None:
    """``"8-15"`` -> ``(8, 15)``, ``"3"`` -> ``(3, 3)``; ``None`` -> every day found."""
    if text is None:
        return None
    m = re.fullmatch(r"\s*(\d+)\s*(?:-\s*(\d+)\s*)?", text)
    if not m:
        raise InputError(f"--days {text!r}: a day or a range A-B (e.g. 1-7)", field="days")
    a, b = int(m.group(1)), int(m.group(2) or m.group(1))
    if a < 1 or b < a:
        raise InputError(f"--days {text!r}: days count from 1 and A <= B", field="days")
    return a, b


@dataclass(frozen=True)
class Day:
    """One day file read: levels ``(n, S)`` int8 and activities ``(n, 2)`` per second (rejected
    lines hold the second before), the rejects, and how many lines there were."""

    number: int
    levels: np.ndarray
    activities: np.ndarray
    rejects: pl.DataFrame
    lines: int


def read_day(path: Path, number: int, n_sensors: int, *, carry: tuple[np.ndarray, np.ndarray] | None = None) -> Day:
    """A day file (module docstring): every line checked, vectorised with polars."""
    try:
        raw = pl.read_csv(
            path,
            has_header=False,
            separator="\x1f",
            quote_char=None,
            new_columns=["raw"],
            schema_overrides={"raw": pl.String},
            infer_schema=False,
        )["raw"]
    except pl.exceptions.NoDataError:
        raw = pl.Series("raw", [], dtype=pl.String)
    except (OSError, pl.exceptions.ComputeError) as exc:
        raise InputError(f"cannot read the day file: {exc}", file=path) from exc
    width = n_sensors + 2
    df = pl.DataFrame({"raw": raw}).with_row_index("line", offset=1)
    df = df.with_columns(f=pl.col("raw").str.strip_chars().str.extract_all(r"\S+"))
    df = df.with_columns(n=pl.col("f").list.len())
    ints = df.select(
        [pl.col("f").list.get(k, null_on_oob=True).cast(pl.Int64, strict=False).alias(f"c{k}") for k in range(width)]
    )
    arr = ints.to_numpy().astype(np.float64) if width else np.zeros((df.height, 0))
    n = df["n"].to_numpy()
    reason = np.full(df.height, "", dtype=object)
    lv, act = arr[:, :n_sensors], arr[:, n_sensors:]
    bad_act = ~np.isnan(act).any(axis=1) & ((act < 1) | (act > N_ACTIVITIES)).any(axis=1)
    bad_lv = ~np.isnan(lv).any(axis=1) & ((lv != 0) & (lv != 1)).any(axis=1)
    reason[bad_act] = f"an activity id outside 1-{N_ACTIVITIES}"
    reason[bad_lv] = "a sensor level that is not 0 or 1"
    reason[np.isnan(arr).any(axis=1)] = "a field that is not an integer"
    reason[n != width] = f"expected {width} fields ({n_sensors} sensor levels, 2 activity ids)"
    extra = np.arange(df.height) >= DAY_S
    reason[extra] = f"beyond the day's {DAY_S} seconds"
    bad = reason != ""
    rejects = pl.DataFrame(
        {
            "file": str(path),
            "line": df["line"].filter(pl.Series(bad)).cast(pl.Int64),
            "reason": reason[bad].tolist(),
            "raw": df["raw"].filter(pl.Series(bad)),
        }
    )
    rows = min(df.height, DAY_S)
    keep = ~bad[:rows]
    levels = lv[:rows].copy()
    acts = act[:rows].copy()
    # a rejected second holds the one before it (the day before's last, for the first line)
    idx = np.where(keep, np.arange(rows), -1)
    idx = np.maximum.accumulate(idx) if rows else idx
    if carry is not None:
        levels = np.vstack([carry[0][None, :], levels])
        acts = np.vstack([carry[1][None, :], acts])
        idx = idx + 1
        idx[idx == 0] = 0
    elif rows and idx[0] < 0:
        first = np.flatnonzero(keep)
        if first.size == 0:
            raise InputError("no usable line in the day file", file=path)
        idx[idx < 0] = first[0]
    levels = levels[idx].astype(np.int8)
    acts = acts[idx].astype(np.int16)
    return Day(number, levels, acts, _rejects(rejects), df.height)


def _rejects(df: pl.DataFrame) -> pl.DataFrame:
    """The canonical rejects table (source file, line, reason, raw text)."""
    return df.rename({"file": "source"}).select(REJECTS.names()).cast(dict(REJECTS))


def runs(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Run-length encoding of a 1-D array: start indices and values of each run.

    >>> [x.tolist() for x in runs(np.array([2, 2, 1, 1, 1, 2]))]
    [[0, 2, 5], [2, 1, 2]]
    """
    if values.size == 0:
        return np.zeros(0, np.int64), values
    start = np.r_[0, np.flatnonzero(values[1:] != values[:-1]) + 1]
    return start, values[start]


def intervals(t: np.ndarray, values: np.ndarray, end: float) -> pl.DataFrame:
    """``t, end, value`` intervals of a per-second series (``t`` its times, ``end`` the last end)."""
    start, v = runs(values)
    ends = np.r_[t[start[1:]], end] if start.size else np.zeros(0)
    return pl.DataFrame({"t": t[start].astype(float), "end": ends.astype(float), "value": v.astype(np.int64)})


def truth_event_residents(acts: np.ndarray) -> np.ndarray:
    """The rule of the module docstring for every second: ``"1"``, ``"2"`` or ``""`` (unknown).

    >>> truth_event_residents(np.array([[1, 2], [11, 12], [12, 13], [2, 16], [12, 11]])).tolist()
    ['1', '2', '', '', '1']
    """
    away = np.isin(acts, (GOING_OUT, SLEEPING, NAPPING))
    out = np.full(len(acts), "", dtype=object)
    out[~away[:, 0] & away[:, 1]] = "1"
    out[away[:, 0] & ~away[:, 1]] = "2"
    return out


def edges(t: np.ndarray, levels: np.ndarray, ids: list[str], *, first: bool) -> pl.DataFrame:
    """Level changes (t, sensor, value) of ``levels`` (n x S) at times ``t``; with ``first`` the
    levels held at ``t[0]`` are written as changes too (a sensor on at the start)."""
    if levels.shape[0] == 0:
        return pl.DataFrame(schema={"t": pl.Float64, "sensor": pl.String, "value": pl.Int8})
    prev = np.vstack([np.zeros((1, levels.shape[1]), levels.dtype) if first else levels[:1], levels[:-1]])
    r, c = np.nonzero(levels != prev)
    order = np.lexsort((c, r))
    r, c = r[order], c[order]
    return pl.DataFrame(
        {"t": t[r].astype(float), "sensor": np.asarray(ids, dtype=object)[c].tolist(), "value": levels[r, c]},
        schema={"t": pl.Float64, "sensor": pl.String, "value": pl.Int8},
    )


def schematic_positions(sensors: list[ArasSensor]) -> dict[str, tuple[float, float]]:
    """Each sensor on a circle inside its room's box (:data:`ROOMS`), in column order."""
    out = {}
    by_room: dict[str, list[ArasSensor]] = {}
    for s in sensors:
        by_room.setdefault(s.room, []).append(s)
    for room, members in by_room.items():
        x0, y0, x1, y1 = ROOMS[room]
        cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
        r = 0.3 * min(x1 - x0, y1 - y0) if len(members) > 1 else 0.0
        for k, s in enumerate(members):
            a = 2 * np.pi * k / len(members)
            out[s.id] = (round(cx + r * np.cos(a), 3), round(cy + r * np.sin(a), 3))
    return out


def schematic_edges(sensors: list[ArasSensor], pos: dict) -> list[tuple[str, str]]:
    """Sensors of one room all joined; between rooms joined by a doorway (the hall to every room,
    :data:`ADJACENT`), their closest pair."""
    out = []
    for i, a in enumerate(sensors):
        for b in sensors[i + 1 :]:
            if a.room == b.room:
                out.append((a.id, b.id))
    rooms = sorted({s.room for s in sensors})
    for i, ra in enumerate(rooms):
        for rb in rooms[i + 1 :]:
            if not ("hall" in (ra, rb) or (ra, rb) in ADJACENT or (rb, ra) in ADJACENT):
                continue
            pairs = [(a, b) for a in sensors if a.room == ra for b in sensors if b.room == rb]
            a, b = min(pairs, key=lambda p: np.hypot(*(np.subtract(pos[p[0].id], pos[p[1].id]))))
            out.append((a.id, b.id))
    if "hall" not in rooms:  # no hall sensor: join every room to the door's room through its closest pair
        pass
    return out


def site_text(house: ArasHouse, name: str) -> str:
    """``site.toml`` of the house's person sensors (module docstring)."""
    person = [s for s in house.sensors if s.person]
    pos = schematic_positions(person)
    edges_ = schematic_edges(person, pos)
    doors = [s.id for s in person if s.door]
    lines = [
        f"# Imported from the ARAS house {Path(house.source).parent.name} by 'onebit import aras' (see import.toml).",
        "# Sensor positions: SCHEMATIC, approximate -- each sensor in its README place's room of a fixed flat",
        "# plan (rooms in the right order, not measured). Sensor graph: sensors of a room joined, rooms through the hall.",
        f"# Time: epoch {EPOCH} is a notional date; day N starts N-1 days after it.",
        f"name = {_v(name)}",
        'units = "m"',
        f"epoch = {_v(EPOCH)}",
        "",
        "[boundary]",
        "polygon = [[-5.0, 0.0], [8.0, 0.0], [8.0, 9.0], [-5.0, 9.0]]",
        "",
    ]
    for typ in sorted({s.type for s in person}):
        lines += [f"[sensor_types.{typ}]", 'signal = "level"', ""]
    for s in person:
        lines += [
            "[[motion_sensors]]",
            f"id = {_v(s.id)}",
            f"type = {_v(s.type)}",
            f"position = {_v(list(pos[s.id]))}",
            "range = 1.0",
            f"# {s.place} ({s.room})",
            "",
        ]
    lines += [
        "[sensor_graph]",
        f"edges = {_v([list(e) for e in edges_])}",
        f"entries = {_v(doors)}",
        f"exits = {_v(doors)}",
        "",
    ]
    return "\n".join(lines)


@dataclass(frozen=True)
class ArasImport:
    out: Path
    counts: dict
    info: dict


def day_files(house: Path) -> dict[int, Path]:
    """``{N: DAY_N.txt}`` of a house folder."""
    out = {}
    for p in house.iterdir() if house.is_dir() else ():
        m = re.fullmatch(r"day_(\d+)\.txt", p.name.lower())
        if m:
            out[int(m.group(1))] = p
    return out


def _annotations(notes: list[pl.DataFrame], spec) -> pl.DataFrame:
    """``annotations.csv``: each resident's activity intervals (merged across days), named from
    the README."""
    return (
        pl.concat(
            [
                _merge_intervals(pl.concat([n for n in notes if n["resident"][0] == r]).drop("resident")).with_columns(
                    resident=pl.lit(r)
                )
                for r in ("1", "2")
            ]
        )
        .rename({"value": "activity"})
        .with_columns(name=pl.col("activity").replace_strict(spec.activities, default="?", return_dtype=pl.String))
        .sort("t", "resident")
        .select("t", "end", "resident", "activity", "name")
    )


def _import_info(house: Path, spec, counts: dict, a: int, b: int) -> dict:
    """``import.toml``: the source, the counts, the notional time and how the truth was made."""
    return {
        "source": {"folder": str(house.resolve()), "format": "aras", "readme": spec.source},
        "counts": counts,
        "time": {
            "epoch": EPOCH,
            "notional": True,
            "days": [a, b],
            "rule": "day N starts (N - 1) x 86400 s after epoch",
        },
        "truth": {
            "count": "people home = residents whose activity is not Going Out (2)",
            "events": "an ON edge goes to resident r when the other is Going Out, Sleeping or Napping and r is not; "
            "other events are unlabelled",
        },
        "sensors": {s.id: {"type": s.type, "place": s.place, "room": s.room, "person": s.person} for s in spec.sensors},
        "layout": {"positions": "schematic (rooms from the README places), approximate"},
    }


@dataclass
class _Days:
    """The tables of the days read so far (:func:`import_aras`)."""

    motion: list = field(default_factory=list)
    other: list = field(default_factory=list)
    counts: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    events: list = field(default_factory=list)
    rejects: list = field(default_factory=list)
    lines: int = 0
    short: int = 0


def _add_day(acc: _Days, day, d: int, spec, carry) -> None:
    """One day's level changes, count intervals, activities and labelled events into ``acc``."""
    ids = [s.id for s in spec.sensors]
    person = {s.id: s.person for s in spec.sensors}
    people_ids = [i for i in ids if person[i]]
    lv, acts = day.levels, day.activities
    t = (d - 1) * DAY_S + np.arange(lv.shape[0])
    acc.lines += day.lines
    acc.short += int(day.lines < DAY_S)
    acc.rejects.append(day.rejects)
    if carry is not None and t.size:  # changes from the day before's last second count, at this day's first
        ch = edges(np.r_[t[0] - 1, t], np.vstack([carry[0][None, :], lv]), ids, first=False)
    else:
        ch = edges(t, lv, ids, first=True)
    kinds = {s.id: s.type for s in spec.sensors}
    acc.motion.append(ch.filter(pl.col("sensor").is_in(people_ids)))
    acc.other.append(
        ch.filter(~pl.col("sensor").is_in(people_ids)).with_columns(
            kind=pl.col("sensor").replace_strict(kinds, default="binary")
        )
    )
    end = float(t[-1] + 1) if t.size else float((d - 1) * DAY_S)
    acc.counts.append(intervals(t, (acts != GOING_OUT).sum(axis=1), end))
    for r in range(2):
        acc.notes.append(intervals(t, acts[:, r], end).with_columns(resident=pl.lit(str(r + 1))))
    who = truth_event_residents(acts)
    on = ch.filter((pl.col("value") == 1) & pl.col("sensor").is_in(people_ids))
    k = (on["t"].to_numpy() - (d - 1) * DAY_S).astype(np.int64)
    acc.events.append(on.select("t", "sensor").with_columns(residents=pl.Series(who[k].tolist(), dtype=pl.String)))


def _write_dataset(out: Path, acc: _Days, spec, name: str) -> dict:
    """Write the dataset's files from the days read; its counts for ``import.toml``."""
    motion_df = pl.concat(acc.motion)
    other_df = pl.concat(acc.other)
    count_df = _merge_intervals(pl.concat(acc.counts)).rename({"value": "count"})
    truth_events = pl.concat(acc.events).filter(pl.col("residents") != "")
    rej = pl.concat(acc.rejects)
    text = site_text(spec, name)
    site_from_dict(tomllib.loads(text), source=str(out / "site.toml"))
    out.mkdir(parents=True, exist_ok=True)
    write_text(text, out / "site.toml")
    write_csv(motion_df, out / "motion.csv")
    if other_df.height:
        write_csv(other_df.select("t", "sensor", "kind", "value"), out / "other.csv")
    write_csv(count_df.select("t", "end", "count"), out / "truth_count.csv")
    write_csv(_annotations(acc.notes, spec), out / "annotations.csv")
    write_csv(truth_events, out / "truth_events.csv")
    if rej.height:
        write_csv(rej, out / "rejects.csv")
    elif (out / "rejects.csv").exists():
        (out / "rejects.csv").unlink()
    return {
        "lines": acc.lines,
        "rejected": rej.height,
        "short_days": acc.short,
        "motion_csv": motion_df.height,
        "other_csv": other_df.height,
        "truth_events": truth_events.height,
        "person_sensors": sum(bool(s.person) for s in spec.sensors),
        "doors": sum(s.door for s in spec.sensors),
    }


def import_aras(house: str | Path, dataset: str | Path, *, days: tuple[int, int] | None = None) -> ArasImport:
    """Write a dataset folder from an ARAS house folder (module docstring)."""
    house, out = Path(house), Path(dataset)
    if not house.is_dir():
        raise InputError("no such ARAS house folder", file=house)
    spec = read_readme(house / "README")
    files = day_files(house)
    if not files:
        raise InputError("no DAY_N.txt files in the house folder", file=house)
    a, b = days if days is not None else (min(files), max(files))
    missing = [d for d in range(a, b + 1) if d not in files]
    if missing:
        raise InputError(f"no day file for day(s) {missing} (found {min(files)}-{max(files)})", file=house)
    acc, carry = _Days(), None
    for d in range(a, b + 1):
        day = read_day(files[d], d, len(spec.sensors), carry=carry)
        _add_day(acc, day, d, spec, carry)
        carry = (day.levels[-1], day.activities[-1]) if day.levels.shape[0] else carry
    counts = {"days": b - a + 1, **_write_dataset(out, acc, spec, f"aras-{house.name}-days-{a}-{b}")}
    info = _import_info(house, spec, counts, a, b)
    write_text(to_toml(info), out / "import.toml")
    write_text(RUN_TOML, out / "run.toml")
    return ArasImport(out, counts, info)


#: The dataset's own ``run.toml``: which trackers a plain ``onebit run`` runs on a home log.
RUN_TOML = """# Written by 'onebit import aras': what a plain 'onebit run' of this home does (edit freely;
# --trackers on the command line overrides it).
# residents: who fired each event, and how many are home (stage occupancy, docs/homes.md).
# Left out by default: hmm1, hmm2, findinghumo, findinghumo-flow decode every 1 s slot of the
#   log (minutes per day of a home; run them with --trackers on a few days); intruder and
#   intruder-naive follow one intruder, not a household.
[run]
trackers = ["residents"]

# a row of each person every 10 s (not every second: a month is then 0.26 M rows a person);
# with a residents_profile.csv, who fired each event by runs of one resident's events weighed
# by their habits (eq. K4 of docs/residents.md: over days one resident is often out or asleep)
[residents]
period = 10.0
profile_model = "turns"
profile_tau_s = 30.0
"""


def _merge_intervals(df: pl.DataFrame) -> pl.DataFrame:
    """Join consecutive intervals of the same value that touch (day boundaries)."""
    if df.height == 0:
        return df
    df = df.sort("t")
    new = (pl.col("value") != pl.col("value").shift(1)) | (pl.col("t") != pl.col("end").shift(1))
    return (
        df.with_columns(g=new.fill_null(True).cum_sum())
        .group_by("g", maintain_order=True)
        .agg(pl.col("t").first(), pl.col("end").last(), pl.col("value").first())
        .drop("g")
    )
