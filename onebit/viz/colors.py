"""Stable per-id colours: an id is hashed (CRC-32, not Python's salted ``hash``) into a fixed
palette, so an agent, track or region keeps its colour in every stage and every run."""

from __future__ import annotations

import zlib
from collections.abc import Iterable

import numpy as np

#: Fixed palette (Tableau 20 order: the 10 strong colours, then their light partners).
PALETTE: np.ndarray = np.array(
    [
        (31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
        (140, 86, 75), (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207),
        (174, 199, 232), (255, 187, 120), (152, 223, 138), (255, 152, 150), (197, 176, 213),
        (196, 156, 148), (247, 182, 210), (199, 199, 199), (219, 219, 141), (158, 218, 229),
    ],
    dtype=np.uint8,
)  # fmt: skip

#: Colours of the static site drawing (RGBA).
WALL = (60, 60, 60, 255)
OBSTACLE = (110, 80, 60, 255)
BEAM = (220, 30, 30, 255)
FORWARD = (40, 160, 60, 255)
BACKWARD = (230, 120, 20, 255)
WARNING = (200, 160, 0, 255)


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
    """``(N, 4)`` uint8 RGBA colours of ``keys``."""
    idx = np.fromiter((palette_index(k) for k in keys), dtype=np.int64)
    out = np.empty((len(idx), 4), dtype=np.uint8)
    out[:, :3] = PALETTE[idx]
    out[:, 3] = alpha
    return out
