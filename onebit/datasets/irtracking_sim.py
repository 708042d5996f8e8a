"""Files in the irtracking formats (Milan et al.'s ceiling array), written from a small simulation.

:func:`write_irtracking` writes what the authors publish for one sequence, for tests and demos
(never their data): ``getSensorCoordinates.m`` (a grid of ``cols x rows`` sensors ``spacing``
mm apart, in the authors' MATLAB layout), ``SEQ.txt`` (start time, then one line of
``channels`` integers per frame with CRLF ends and a trailing blank, the sensor's number where
it is active), ``SEQ_gt.xml`` (CVML truth, pixels = mm / 25) and ``SEQ.xml`` (CVML detections:
each active sensor as a box at its position). People walk straight lines at constant speed
between random points of the room; a sensor is active in a frame when someone is within
``radius_mm`` of it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from onebit.core.writers import write_text
from onebit.readers.irtracking import CHANNELS, PIXEL_MM


@dataclass(frozen=True)
class IrtrackingFiles:
    coordinates: Path
    readings: Path
    truth: Path
    detections: Path
    sensors_mm: np.ndarray  # (n, 2)
    truth_mm: dict[int, dict[int, tuple[float, float]]]  # frame -> person -> (x, y) mm
    active: dict[int, list[int]]  # frame -> active sensor numbers (1-based)


def sensor_grid(cols: int, rows: int, spacing: float) -> np.ndarray:
    """``(cols * rows, 2)`` positions (mm) of a grid starting at ``spacing / 2``."""
    x, y = np.meshgrid(spacing / 2 + spacing * np.arange(cols), spacing / 2 + spacing * np.arange(rows))
    return np.c_[x.ravel(), y.ravel()]


def coordinates_m(xy: np.ndarray) -> str:
    """``getSensorCoordinates.m`` for positions ``xy`` (mm), laid out as the authors' file."""

    def vec(v: np.ndarray) -> str:
        rows = [
            " ".join(f"{int(round(a)):04d}" for a in v[i : i + 10]) + " ... % " + f"{i + 1}..{i + 10}"
            for i in range(0, len(v), 10)
        ]
        return "\n ".join(rows)

    return (
        "function [xc, yc]=getSensorCoordinates\n\n%   a test grid\n\nxc=[ ...\n " + vec(xy[:, 0]) + "\n];\n\n"
        "yc=[ ...\n " + vec(xy[:, 1]) + "\n];\n\n% xc=xc/2;\nend\n"
    )


def cvml(frames: dict[int, list[tuple[str | None, float, float]]]) -> str:
    """A CVML document: per frame, objects ``(id or None, x_mm, y_mm)`` as 28-pixel boxes."""
    out = ['<?xml version="1.0" encoding="utf-8"?>', '<dataset name="PRML">']
    for f in sorted(frames):
        objs = frames[f]
        out.append(f'   <frame number="{f}">')
        if not objs:
            out.append("      <objectlist/>")
        else:
            out.append("      <objectlist>")
            for oid, x, y in objs:
                attr = f'id="{oid}"' if oid is not None else 'confidence="1"'
                out += [
                    f"         <object {attr}>",
                    f'            <box h="28" w="28" xc="{x / PIXEL_MM:.4f}" yc="{y / PIXEL_MM:.4f}"/>',
                    "         </object>",
                ]
            out.append("      </objectlist>")
        out.append("   </frame>")
    out.append("</dataset>")
    return "\n".join(out) + "\n"


def write_irtracking(
    folder: str | Path,
    *,
    name: str = "seq",
    frames: int = 40,
    people: int = 2,
    cols: int = 4,
    rows: int = 6,
    spacing: float = 1500.0,
    radius_mm: float = 800.0,
    speed_mm_s: float = 1000.0,
    period: float = 0.5,
    seed: int = 0,
) -> IrtrackingFiles:
    """Write one simulated sequence in the irtracking formats (module docstring)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    xy = sensor_grid(cols, rows, spacing)
    if len(xy) > CHANNELS:
        raise ValueError(f"{len(xy)} sensors do not fit the {CHANNELS} channels of a reading line")
    w, h = cols * spacing, rows * spacing
    truth: dict[int, dict[int, tuple[float, float]]] = {f: {} for f in range(1, frames + 1)}
    for p in range(1, people + 1):
        first = int(rng.integers(1, max(frames // 3, 2)))
        pos = rng.uniform([0.2 * w, 0.2 * h], [0.8 * w, 0.8 * h])
        goal = rng.uniform([0.1 * w, 0.1 * h], [0.9 * w, 0.9 * h])
        for f in range(first, frames + 1):
            truth[f][p] = (float(pos[0]), float(pos[1]))
            d = goal - pos
            step = speed_mm_s * period
            if np.hypot(*d) <= step:
                pos, goal = goal, rng.uniform([0.1 * w, 0.1 * h], [0.9 * w, 0.9 * h])
            else:
                pos = pos + d / np.hypot(*d) * step
    active: dict[int, list[int]] = {}
    lines = ["2013-9-25 15:47:25"]
    for f in range(1, frames + 1):
        on = np.zeros(CHANNELS, dtype=np.int64)
        for x, y in truth[f].values():
            near = np.hypot(xy[:, 0] - x, xy[:, 1] - y) <= radius_mm
            on[: len(xy)][near] = np.flatnonzero(near) + 1
        active[f] = [int(k) for k in np.flatnonzero(on) + 1]
        lines.append(" ".join(str(v) for v in on) + " ")
    paths = IrtrackingFiles(
        folder / "getSensorCoordinates.m",
        folder / f"{name}.txt",
        folder / f"{name}_gt.xml",
        folder / f"{name}.xml",
        xy,
        truth,
        active,
    )
    write_text(coordinates_m(xy), paths.coordinates)
    paths.readings.write_bytes(("\r\n".join(lines)).encode())
    write_text(cvml({f: [(str(p), *truth[f][p]) for p in truth[f]] for f in truth}), paths.truth)
    write_text(cvml({f: [(None, *xy[k - 1]) for k in active[f]] for f in active}), paths.detections)
    return paths
