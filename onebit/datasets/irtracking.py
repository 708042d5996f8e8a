"""``onebit import irtracking READINGS DATASET_DIR [--truth GT.xml]``: the ceiling array of Milan et al.

The recordings of *Privacy preserving multi-target tracking* (Milan, Roth, Schindler, Kudo;
ACCV 2014 workshops): 43 binary infrared sensors on the ceiling of an 8 m x 14 m room, read
at 2 frames per second (``frameRate = 2`` in the authors' ``getSceneInfo.m``), with people's
positions annotated by hand in CVML. The importer writes a dataset folder::

    site.toml     the room (boundary [0, 8] x [0, 14] m, the authors' tracking area), the 43
                  sensors declared once as [[binary_sensors]] (position in metres, footprint
                  disk, signal = "level": a sensor held on is presence), ``targets`` and a
                  sensor graph from the geometry (``geometry = "connected"``: neighbours
                  within the smallest distance that keeps the array connected; the authors'
                  1.5 m rule splits it into pieces)
    frames.csv    one row per frame: t, active (the ids of the active sensors, space-separated)
    truth.csv     t, target, x, y in metres (with --truth)
    rejects.csv   every input line not taken, with its reason (when there are any)
    import.toml   what was done: counts, period, start time, where positions came from

Frame ``k`` (1-based) is at ``t = (k - 1) * period`` seconds (``period`` = 0.5 s); the truth's
frame ``k`` is at the same ``t``. ``READINGS`` is a readings file (``SEQ.txt``) or the
authors' detections in CVML (``SEQ.xml``: each active sensor as a box at its position; each
box is mapped to the sensor at that position, within ``tolerance_mm``), so the sequences
published only as XML (``testanton*``) import too.

``targets`` is **not** taken from the truth (a user does not know it): it is ``--targets`` if
given, else :data:`DEFAULT_TARGETS`, the most people the recordings were made with (the
paper's "up to six"); every tracker treats it as an upper bound.

The footprint is a disk of radius ``radius`` (default :data:`DEFAULT_RADIUS_M`) around each
sensor: the sensors are 1.3-1.6 m apart, so disks of that radius overlap their neighbours'
a little and cover the floor between them (the importer's ``import.toml`` records the value).
Sensor positions come from the authors' ``getSensorCoordinates.m`` (millimetres), found next
to the readings or up to two folders above, or given with ``--coordinates``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import polars as pl

from onebit.core.errors import InputError
from onebit.core.site import load_site
from onebit.core.tables import REJECTS
from onebit.core.writers import to_toml, write_csv, write_text
from onebit.readers.irtracking import read_cvml, read_readings_txt, read_sensor_coordinates

#: Seconds between frames (the authors' ``frameRate = 2``).
PERIOD_S = 0.5
#: Footprint radius of a ceiling sensor, metres (module docstring).
DEFAULT_RADIUS_M = 1.0
#: ``targets`` when not given: the most people of the recordings (Milan et al.: up to six).
DEFAULT_TARGETS = 6
#: The room (the authors' tracking area, ``[0 8000 0 14000]`` mm), metres.
ROOM_M = (8.0, 14.0)
#: A detection box is the sensor within this many millimetres of its centre.
TOLERANCE_MM = 100.0
#: Name of the authors' coordinates file.
COORDINATES_FILE = "getSensorCoordinates.m"
#: The sensor type every imported sensor has: its reading is a level.
SENSOR_TYPE = "ceiling-ir"


@dataclass(frozen=True)
class IrtrackingImport:
    """What :func:`import_irtracking` wrote (also in ``import.toml``)."""

    dataset: Path
    info: dict


def find_coordinates(readings: Path) -> Path:
    """``getSensorCoordinates.m`` next to ``readings`` or up to two folders above it."""
    for folder in (readings.parent, *list(readings.parents)[1:3]):
        cand = folder / COORDINATES_FILE
        if cand.exists():
            return cand
    raise InputError(
        f"no {COORDINATES_FILE} next to the readings or up to two folders above; give it with --coordinates",
        file=readings,
    )


def _active_from_detections(
    path: Path, xy_mm: np.ndarray, tolerance_mm: float
) -> tuple[pl.DataFrame, tuple[int, ...], pl.DataFrame]:
    """Detections (CVML boxes at sensor positions) -> frame, sensor; boxes far from every sensor rejected."""
    cv = read_cvml(path)
    obj = cv.objects
    rejects = [cv.rejects]
    if obj.height:
        pts = obj.select("x", "y").to_numpy()
        d = np.hypot(pts[:, None, 0] - xy_mm[None, :, 0], pts[:, None, 1] - xy_mm[None, :, 1])
        near = np.argmin(d, axis=1)
        ok = d[np.arange(len(pts)), near] <= tolerance_mm
        obj = obj.with_columns(sensor=pl.Series((near + 1).astype(str)), _ok=pl.Series(ok))
        bad = obj.filter(~pl.col("_ok"))
        if bad.height:
            rejects.append(
                bad.select(
                    source=pl.lit(path.name),
                    line=pl.col("line"),
                    reason=pl.format(
                        "box at ({}, {}) mm is not within {} mm of a sensor",
                        pl.col("x").round(0),
                        pl.col("y").round(0),
                        pl.lit(tolerance_mm),
                    ),
                    raw=pl.lit(None, pl.String),
                ).cast(dict(REJECTS))
            )
        obj = obj.filter("_ok")
    else:
        obj = obj.with_columns(sensor=pl.lit(None, pl.String))
    active = obj.select("frame", "sensor").unique(maintain_order=True)
    return active, cv.frames, pl.concat(rejects)


def frames_table(active: pl.DataFrame, frames: tuple[int, ...] | range, period: float, first: int) -> pl.DataFrame:
    """``frames.csv`` rows: one per frame, ``t`` and the active sensor ids (space-separated,
    in sensor order; empty when none)."""
    allf = pl.DataFrame({"frame": list(frames)}, schema={"frame": pl.Int64})
    lists = (
        active.with_columns(_k=pl.col("sensor").cast(pl.Int64, strict=False))
        .sort("frame", "_k")
        .group_by("frame", maintain_order=True)
        .agg(active=pl.col("sensor").str.join(" "))
    )
    out = allf.join(lists, on="frame", how="left").sort("frame")
    return out.select(t=(pl.col("frame") - first).cast(pl.Float64) * period, active=pl.col("active").fill_null(""))


def truth_table(path: Path, period: float, first: int) -> tuple[pl.DataFrame, pl.DataFrame, int]:
    """``truth.csv`` rows (t, target, x, y in metres) from a CVML truth file; objects without
    an ``id`` are rejected (a detections file given as truth)."""
    cv = read_cvml(path)
    obj = cv.objects
    no_id = obj.filter(pl.col("object").is_null())
    rej = [cv.rejects]
    if no_id.height:
        rej.append(
            no_id.select(
                source=pl.lit(path.name),
                line=pl.col("line"),
                reason=pl.lit("object without an id (not a truth annotation)"),
                raw=pl.lit(None, pl.String),
            ).cast(dict(REJECTS))
        )
    truth = (
        obj.filter(pl.col("object").is_not_null())
        .select(
            t=(pl.col("frame") - first).cast(pl.Float64) * period,
            target=pl.col("object"),
            x=pl.col("x") / 1000.0,
            y=pl.col("y") / 1000.0,
        )
        .sort("t", "target")
    )
    return truth, pl.concat(rej), len(cv.frames)


def site_toml(
    xy_m: np.ndarray, *, name: str, radius: float, r_inner: float | None, targets: int, start: str | None
) -> str:
    """The dataset's ``site.toml``: the room, the sensors declared once, ``targets``."""
    w, h = ROOM_M
    lines = [
        "# Imported by 'onebit import irtracking' (Milan et al.'s ceiling array; see import.toml).",
        f"# Recording start: {start or 'not given'}; t = 0 is the first frame.",
        f'name = "{name}"',
        'units = "m"',
        f"targets = {int(targets)}   # an upper bound on the people present at once (not from the truth)",
        "",
        "[boundary]",
        f"polygon = [[0.0, 0.0], [{w!r}, 0.0], [{w!r}, {h!r}], [0.0, {h!r}]]",
        "",
        f"[sensor_types.{SENSOR_TYPE}]",
        'signal = "level"   # a sensor held on is presence under it',
        "",
        "[sensor_graph]     # for the graph trackers: neighbours within the smallest distance that keeps the array connected",
        'geometry = "connected"',
    ]
    foot = f"radius = {radius!r}" if r_inner is None else f"r_outer = {radius!r}\nr_inner = {r_inner!r}"
    for i, (x, y) in enumerate(xy_m, start=1):
        lines += [
            "",
            "[[binary_sensors]]",
            f'id = "{i}"',
            f"position = [{float(x)!r}, {float(y)!r}]",
            foot,
            f'type = "{SENSOR_TYPE}"',
        ]
    return "\n".join(lines) + "\n"


def _check_args(period: float, radius: float, r_inner: float | None, targets: int | None) -> None:
    """The import's numbers, each checked (the error names the argument)."""
    if not (period > 0 and np.isfinite(period)):
        raise InputError(f"period = {period!r}: must be a positive number of seconds", field="period")
    if not (radius > 0 and np.isfinite(radius)):
        raise InputError(f"radius = {radius!r}: must be a positive number of metres", field="radius")
    if r_inner is not None and not (0 <= r_inner <= radius):
        raise InputError(f"r_inner = {r_inner!r}: must be between 0 and radius ({radius!r})", field="r_inner")
    if targets is not None and (isinstance(targets, bool) or not isinstance(targets, int) or targets < 1):
        raise InputError(f"targets = {targets!r}: must be a whole number >= 1", field="targets")


def _import_info(
    readings, source, coords, truth, period, start, first, radius, r_inner, n_targets, targets, counts
) -> dict:
    """``import.toml``: the sources, the time base, the site's choices and the counts."""
    return {
        "source": {
            "readings": str(readings),
            "kind": source,
            "coordinates": str(coords),
            "truth": str(truth) if truth else "",
        },
        "time": {"period_s": float(period), "start": start or "", "t0_frame": int(first)},
        "site": {
            "radius_m": float(radius),
            "r_inner_m": float(r_inner if r_inner is not None else radius),
            "targets": int(n_targets),
            "targets_from": "--targets"
            if targets is not None
            else f"default ({DEFAULT_TARGETS}: the recordings' most people)",
        },
        "counts": counts,
    }


def import_irtracking(
    readings: str | Path,
    dataset: str | Path,
    *,
    truth: str | Path | None = None,
    coordinates: str | Path | None = None,
    period: float = PERIOD_S,
    radius: float = DEFAULT_RADIUS_M,
    r_inner: float | None = None,
    targets: int | None = None,
    name: str | None = None,
    tolerance_mm: float = TOLERANCE_MM,
) -> IrtrackingImport:
    """Import one irtracking sequence into ``dataset`` (module docstring); returns what was written."""
    readings, out = Path(readings), Path(dataset)
    if not readings.exists():
        raise InputError("no such file", file=readings)
    _check_args(period, radius, r_inner, targets)
    coords = Path(coordinates) if coordinates is not None else find_coordinates(readings)
    xy_mm = read_sensor_coordinates(coords)
    start = None
    counts: dict = {}
    if readings.suffix.lower() == ".xml":
        active, frames, rejects = _active_from_detections(readings, xy_mm, tolerance_mm)
        source = "CVML detections (boxes at sensor positions)"
    else:
        rd = read_readings_txt(readings, sensors=len(xy_mm))
        active, frames, rejects = rd.active, range(1, rd.frames + 1), rd.rejects
        start = rd.start.isoformat() if rd.start is not None else None
        counts |= {"ignored_active_channels": rd.extra_active, "relabelled_values": rd.relabelled}
        source = "readings (one line of channels per frame)"
    if not len(frames):
        raise InputError("no frame in the readings", file=readings)
    first = min(frames)
    ft = frames_table(active, frames, period, first)
    truth_df = None
    if truth is not None:
        truth_df, trej, truth_frames = truth_table(Path(truth), period, first)
        rejects = pl.concat([rejects, trej])
        counts |= {
            "truth_frames": truth_frames,
            "truth_rows": truth_df.height,
            "truth_targets": truth_df["target"].n_unique(),
        }
    n_targets = targets if targets is not None else DEFAULT_TARGETS
    xy_m = xy_mm / 1000.0
    name = name or readings.stem
    out.mkdir(parents=True, exist_ok=True)
    text = site_toml(xy_m, name=name, radius=float(radius), r_inner=r_inner, targets=n_targets, start=start)
    write_text(text, out / "site.toml")
    load_site(out / "site.toml")  # what was written loads (a sensor outside the room would fail here, naming it)
    write_csv(ft, out / "frames.csv")
    if truth_df is not None:
        write_csv(truth_df, out / "truth.csv")
    if rejects.height:
        write_csv(rejects, out / "rejects.csv")
    counts |= {
        "frames": ft.height,
        "sensors": len(xy_mm),
        "active_readings": active.height,
        "rejected": rejects.height,
    }
    info = _import_info(
        readings, source, coords, truth, period, start, first, radius, r_inner, n_targets, targets, counts
    )
    write_text(to_toml(info), out / "import.toml")
    return IrtrackingImport(out, info)
