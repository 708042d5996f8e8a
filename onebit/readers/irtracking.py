"""The files of the privacy-preserving ceiling array of Milan, Roth, Schindler & Kudo (``irtracking``).

Three formats, each read into a polars table with a ``rejects`` table beside it (every input
line not taken, with its file, line and reason):

* **readings** ``SEQ.txt`` (:func:`read_readings_txt`): the first line is the start time
  (``2013-9-19 16:12:40``), then one line per frame of whitespace-separated integers, one per
  channel (50 in the recordings, of which the first 43 are the ceiling sensors, as in the
  authors' ``readData.m``); a non-zero value is an active sensor (the recordings write the
  sensor's own number). Frame ``k`` (1-based, in file order) is the ``k``-th reading line. A
  line with another number of fields, or a field that is not an integer, is rejected (the
  authors' reader skips such lines too; the frame count then follows the lines kept, as
  theirs does). Returns one row per frame and active sensor: ``frame``, ``sensor``.
* **CVML** ``SEQ_gt.xml`` (truth) and ``SEQ.xml`` (the authors' detections: each active
  sensor as a box at its position) (:func:`read_cvml`): ``<frame number=...>`` with
  ``<object id=...|confidence=...><box xc=... yc=... w=... h=.../>``; positions are in
  pixels, ``PIXEL_MM`` (25) mm each. Returns ``frame``, ``object`` (the id, null for a
  detection), ``x``, ``y`` in millimetres, plus the frame numbers seen (frames with an empty
  object list are frames too).
* **sensor coordinates** ``getSensorCoordinates.m`` (:func:`read_sensor_coordinates`): the
  MATLAB vectors ``xc = [...]`` and ``yc = [...]`` in millimetres; sensor ``i`` (1-based) is
  at ``(xc(i), yc(i))``.
"""

from __future__ import annotations

import re
import xml.parsers.expat
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.errors import InputError, bounded
from onebit.core.tables import REJECTS, rejects_frame
from onebit.readers.rows import read_bytes

#: Millimetres per pixel of the authors' CVML files ("positions in pixels x 25 = mm").
PIXEL_MM = 25.0
#: Channels per reading line in the recordings, and how many of them are ceiling sensors.
CHANNELS = 50
SENSORS = 43

#: Table of :func:`read_readings_txt`: one row per frame and active sensor.
ACTIVE = pl.Schema({"frame": pl.Int64, "sensor": pl.String})
#: Table of :func:`read_cvml`: one row per object of a frame, millimetres.
CVML_OBJECTS = pl.Schema({"frame": pl.Int64, "object": pl.String, "x": pl.Float64, "y": pl.Float64, "line": pl.Int64})


@dataclass(frozen=True)
class Readings:
    """What :func:`read_readings_txt` made of a readings file."""

    active: pl.DataFrame  # ACTIVE: frame, sensor (every active sensor of every frame)
    frames: int  # reading lines kept (frames 1..frames)
    start: datetime | None  # the first line's time, when it is one
    rejects: pl.DataFrame  # REJECTS
    extra_active: int = 0  # non-zero values in channels beyond the sensors (ignored, counted)
    relabelled: int = 0  # non-zero values that differ from their channel's number (taken as active, counted)


def _start_time(text: str) -> datetime | None:
    m = re.fullmatch(r"\s*(\d{4})-(\d{1,2})-(\d{1,2})[ T](\d{1,2}):(\d{1,2}):(\d{1,2}(?:\.\d+)?)\s*", text)
    if not m:
        return None
    y, mo, d, h, mi = (int(g) for g in m.groups()[:5])
    sec = float(m.group(6))
    try:
        return datetime(y, mo, d, h, mi, int(sec), int(round((sec - int(sec)) * 1e6)))
    except ValueError:
        return None


def read_readings_txt(path: str | Path, *, channels: int = CHANNELS, sensors: int = SENSORS) -> Readings:
    """Read an irtracking readings file (module docstring): the active sensors of each frame.

    Sensor ids are the channel numbers ``"1"`` .. ``str(sensors)``. Raises
    :class:`~onebit.core.errors.InputError` naming the file when no line is a reading.
    """
    path = Path(path)
    if sensors < 1 or channels < sensors:
        raise InputError(f"channels = {channels}, sensors = {sensors}: need 1 <= sensors <= channels", file=path)
    text = read_bytes(path).decode("utf-8", errors="replace")  # a long line or a binary file refused
    lines = text.splitlines()
    start = _start_time(lines[0]) if lines else None
    rows: list[list[int]] = []
    rejects: list[tuple[str, int | None, str, str | None]] = []
    first = 1 if start is not None else 0
    for no, line in enumerate(lines[first:], start=first + 1):
        parts = line.split()
        if not parts:
            continue  # a blank line (the file's end) is no reading
        if len(parts) != channels:
            rejects.append(
                (path.name, no, f"{len(parts)} fields, expected {channels} (one per channel)", bounded(line))
            )
            continue
        try:
            rows.append([int(p) for p in parts])
        except ValueError:
            bad = next(p for p in parts if not re.fullmatch(r"[+-]?\d+", p))
            rejects.append((path.name, no, f"field {bounded(bad, 40)!r} is not an integer", bounded(line)))
    if not rows:
        raise InputError(f"no reading line ({channels} integers) in the file", file=path)
    m = np.asarray(rows, dtype=np.int64)
    on = m[:, :sensors] != 0
    f, s = np.nonzero(on)
    relabelled = int(np.count_nonzero(on & (m[:, :sensors] != np.arange(1, sensors + 1)[None, :])))
    active = pl.DataFrame({"frame": (f + 1).astype(np.int64), "sensor": (s + 1).astype(str)}, schema=ACTIVE)
    return Readings(active, len(rows), start, rejects_frame(rejects), int(np.count_nonzero(m[:, sensors:])), relabelled)


@dataclass(frozen=True)
class Cvml:
    """What :func:`read_cvml` made of a CVML file."""

    objects: pl.DataFrame  # CVML_OBJECTS (millimetres)
    frames: tuple[int, ...]  # every frame number, in file order
    rejects: pl.DataFrame  # REJECTS


def read_cvml(path: str | Path, *, pixel_mm: float = PIXEL_MM) -> Cvml:
    """Read a CVML file (module docstring): every object's box centre, in millimetres.

    An object without a ``<box>`` or with a non-numeric ``xc``/``yc``, or outside a frame, is
    rejected with its line; a duplicate frame number or a malformed document raises
    :class:`~onebit.core.errors.InputError` naming the file and line.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", file=path) from None
    parser = xml.parsers.expat.ParserCreate()
    frames: list[int] = []
    seen: set[int] = set()
    rows: list[tuple[int, str | None, float, float, int]] = []
    rejects: list[tuple[str, int | None, str, str | None]] = []
    state: dict = {"frame": None, "object": None, "box": False}

    def start(name: str, attrs: dict) -> None:
        line = parser.CurrentLineNumber
        if name == "frame":
            num = attrs.get("number")
            if num is None or not re.fullmatch(r"\s*\d+\s*", num):
                raise InputError(
                    f"<frame> number {bounded(str(num), 40)!r} is not a whole number",
                    file=path,
                    line=line,
                    field="number",
                )
            n = int(num)
            if n in seen:
                raise InputError(f"frame {n} appears twice", file=path, line=line, field="number")
            seen.add(n)
            frames.append(n)
            state["frame"] = n
        elif name == "object":
            state["object"] = (attrs.get("id"), line, False)
        elif name == "box":
            obj = state["object"]
            if state["frame"] is None or obj is None:
                rejects.append((path.name, line, "<box> outside a frame's object", None))
                return
            try:
                x, y = float(attrs["xc"]) * pixel_mm, float(attrs["yc"]) * pixel_mm
            except (KeyError, ValueError):
                rejects.append((path.name, line, "<box> without numeric xc and yc", bounded(repr(attrs))))
                state["object"] = (obj[0], obj[1], True)
                return
            if not (np.isfinite(x) and np.isfinite(y)):
                rejects.append((path.name, line, "<box> xc/yc not finite", bounded(repr(attrs))))
                state["object"] = (obj[0], obj[1], True)
                return
            rows.append((state["frame"], obj[0], x, y, line))
            state["object"] = (obj[0], obj[1], True)

    def end(name: str) -> None:
        if name == "object":
            oid, line, had_box = state["object"]
            if not had_box:
                rejects.append((path.name, line, "<object> without a <box>", None))
            state["object"] = None
        elif name == "frame":
            state["frame"] = None

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.Parse(data, True)
    except xml.parsers.expat.ExpatError as exc:
        raise InputError(
            f"not well-formed XML: {xml.parsers.expat.ErrorString(exc.code)}", file=path, line=exc.lineno
        ) from None
    objects = pl.DataFrame(rows, schema=CVML_OBJECTS, orient="row")
    return Cvml(objects, tuple(frames), rejects_frame(rejects))


_VECTOR = re.compile(r"\b(xc|yc)\s*=\s*\[(.*?)\]", re.S)


def read_sensor_coordinates(path: str | Path) -> np.ndarray:
    """``(n, 2)`` sensor positions in millimetres from ``getSensorCoordinates.m`` (module
    docstring): MATLAB comments (``%`` to the line's end) and continuations (``...``) are
    removed, then the numbers of ``xc = [...]`` and ``yc = [...]`` are read. Raises
    :class:`~onebit.core.errors.InputError` naming the file and the vector when one is
    missing, holds a non-number, or the two differ in length."""
    path = Path(path)
    text = read_bytes(path).decode("utf-8", errors="replace")  # a long line or a binary file refused
    code = "\n".join(line.split("%", 1)[0].replace("...", " ") for line in text.splitlines())
    found: dict[str, list[float]] = {}
    for m in _VECTOR.finditer(code):
        name, body = m.group(1), m.group(2)
        items = [p for p in re.split(r"[\s,;]+", body) if p]
        try:
            found[name] = [float(p) for p in items]
        except ValueError:
            bad = next(p for p in items if not re.fullmatch(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?", p))
            line = code[: m.start()].count("\n") + 1
            raise InputError(f"{bounded(bad, 40)!r} is not a number", file=path, line=line, field=name) from None
    for name in ("xc", "yc"):
        if name not in found:
            raise InputError(f"no vector '{name} = [...]' (sensor {name[0]} coordinates, mm)", file=path, field=name)
    if len(found["xc"]) != len(found["yc"]) or not found["xc"]:
        raise InputError(
            f"xc has {len(found['xc'])} numbers, yc {len(found['yc'])}: one per sensor each", file=path, field="yc"
        )
    xy = np.c_[found["xc"], found["yc"]]
    if not np.all(np.isfinite(xy)):
        raise InputError("a coordinate is not finite", file=path, field="xc")
    return xy


def empty_rejects() -> pl.DataFrame:
    return pl.DataFrame(schema=REJECTS)
