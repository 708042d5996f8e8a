"""Colours of a recording.

* Ids (regions, element slots, sensors) are hashed (CRC-32, not Python's salted ``hash``) into
  a fixed palette, so an id keeps its colour in every stage and every run (:func:`color_of`).
* **Truth is neutral** (:data:`TRUTH`: light grey rings and trails) and **every estimate is in
  its tracker's colour** (:func:`track_color`: shades of its
  :class:`~onebit.viz.families.Look`'s ``rgb``), so a true target and an estimate never share a
  colour, whatever their ids.
"""

from __future__ import annotations

import colorsys
import zlib
from collections.abc import Iterable

import numpy as np
import polars as pl

#: Fixed palette (Tableau 20 order: the 10 strong colours, then their light partners).
PALETTE: np.ndarray = np.array(
    [
        (31, 119, 180),
        (255, 127, 14),
        (44, 160, 44),
        (214, 39, 40),
        (148, 103, 189),
        (140, 86, 75),
        (227, 119, 194),
        (127, 127, 127),
        (188, 189, 34),
        (23, 190, 207),
        (174, 199, 232),
        (255, 187, 120),
        (152, 223, 138),
        (255, 152, 150),
        (197, 176, 213),
        (196, 156, 148),
        (247, 182, 210),
        (199, 199, 199),
        (219, 219, 141),
        (158, 218, 229),
    ],
    dtype=np.uint8,
)

#: Colours of the static site drawing (RGBA).
WALL = (150, 150, 150, 255)
OBSTACLE = (150, 120, 95, 255)
BEAM = (220, 30, 30, 255)
FORWARD = (40, 200, 80, 255)
BACKWARD = (240, 140, 30, 255)
WARNING = (230, 190, 0, 255)

#: Background of the map views (the blueprint sets it; opaque overlays such as the I-state
#: fill are composited onto it, since Rerun draws images opaque).
MAP_BACKGROUND = (16, 16, 20, 255)

#: Ground truth: a hollow ring with its label below, and its trail, all neutral.
TRUTH = (235, 235, 235, 255)
TRUTH_TRAIL = (200, 200, 200, 170)

#: A sensor firing now (state timelines, detections).
FIRING = (255, 60, 50, 255)


def palette_index(key: object) -> int:
    """Index into :data:`PALETTE` of ``key`` (its ``str``), the same in every process."""
    return zlib.crc32(str(key).encode("utf-8")) % len(PALETTE)


def color_of(key: object, *, alpha: int = 255) -> tuple[int, int, int, int]:
    """RGBA colour of one id.

    Examples
    --------
    >>> color_of("agent-1") == color_of("agent-1")
    True
    """
    r, g, b = (int(c) for c in PALETTE[palette_index(key)])
    return (r, g, b, int(alpha))


def colors_of(keys: Iterable[object], *, alpha: int = 255) -> np.ndarray:
    """``(N, 4)`` uint8 RGBA colours of ``keys`` (a list or a numpy array).

    Integers, booleans and strings are looked up once per distinct key and gathered (the 1.9
    million particles of a 10^5-row binpf run are a few hundred tracks: 2 s of Python per
    particle before); other keys one by one."""
    values = keys if isinstance(keys, np.ndarray) else np.asarray(list(keys))
    values = values.reshape(-1)
    if values.dtype.kind == "U" and values.size:  # numpy strings sort slowly: hashed by polars
        texts = pl.Series("key", values, dtype=pl.String)
        distinct = texts.unique()
        per_key = [palette_index(k) for k in distinct.to_list()]
        idx = texts.replace_strict(distinct, per_key, return_dtype=pl.Int64).to_numpy()
    elif values.dtype.kind in "biu":  # not floats: 0.0 and -0.0 are one value, two texts
        distinct, inverse = np.unique(values, return_inverse=True)
        per_key = np.fromiter((palette_index(k) for k in distinct.tolist()), dtype=np.int64, count=len(distinct))
        idx = per_key[inverse.reshape(-1)]
    else:
        idx = np.fromiter((palette_index(k) for k in values.tolist()), dtype=np.int64, count=len(values))
    out = np.empty((len(idx), 4), dtype=np.uint8)
    out[:, :3] = PALETTE[idx]
    out[:, 3] = alpha
    return out


#: Colour of the camera's detections (not a tracker: they are drawn as tracks of ``camera``).
CAMERA_RGB: tuple[int, int, int] = (165, 165, 165)


def tracker_color(
    tracker: str, *, rgb: tuple[int, int, int] | None = None, alpha: int = 255
) -> tuple[int, int, int, int]:
    """RGBA colour of a tracker: ``rgb`` (its :class:`~onebit.viz.families.Look`'s), else a
    palette colour from its name."""
    if rgb is None:
        return color_of(tracker, alpha=alpha)
    return (*rgb, int(alpha))


def track_color(
    tracker: str, index: int, count: int, *, rgb: tuple[int, int, int] | None = None, alpha: int = 255
) -> tuple[int, int, int, int]:
    """RGBA colour of the ``index``-th of ``count`` tracks of ``tracker`` (colour ``rgb``, as
    :func:`tracker_color`): the tracker's colour turned a little round the colour wheel and made
    darker (first) to lighter (last), so the tracks of one tracker are told apart and still read
    as that tracker's.

    Examples
    --------
    >>> track_color("beams", 0, 1, rgb=(64, 196, 255)) == tracker_color("beams", rgb=(64, 196, 255))
    True
    """
    r, g, b, _ = tracker_color(tracker, rgb=rgb)
    if count <= 1:
        return (r, g, b, int(alpha))
    s = index / (count - 1) - 0.5  # -0.5 (first) .. 0.5 (last)
    h, l, sat = colorsys.rgb_to_hls(r / 255, g / 255, b / 255)
    h = (h + 0.09 * s) % 1.0
    l = min(max(l + 0.3 * s, 0.35), 0.85)
    r, g, b = (round(255 * c) for c in colorsys.hls_to_rgb(h, l, sat))
    return (r, g, b, int(alpha))
