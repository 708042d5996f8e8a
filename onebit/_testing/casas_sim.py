"""A CASAS-format log of one resident walking a home's hallway (for tests and try-outs).

Writes the text format of the CASAS smart-home datasets (``YYYY-MM-DD HH:MM:SS.ffffff<TAB>
sensor<TAB>value[<TAB>annotation]``, see :mod:`onebit.readers.casas`) for a made-up home:
a straight hallway of ceiling PIRs ``M001``..``M008`` every 3 m, the front door ``D001``
before ``M001``, a side room (``M009``, ``M010``) off ``M005``, a closet door ``D002`` at
``M008``, a thermometer ``T001`` and a light switch ``L001``. The resident comes in through
the front door, walks to rooms and back at 0.8-1.3 m/s, lingers, leaves, comes back.

The log has what real ones have: a PIR sends ``ON`` when the resident enters its 1.5 m
zone, repeats ``ON`` every ~1 s while the resident moves under it (repeated ``ON``) and
``OFF`` 1-2.5 s after the resident left; doors send ``OPEN``/``CLOSE``; lines reach the log
in gateway order, so stamps are up to 0.7 s out of order; activity annotations on some
lines; temperature every minute. :data:`LAYOUT` gives the true sensor positions. Nothing
comes from a real dataset. Deterministic for a seed.
"""

from __future__ import annotations

from datetime import datetime, timedelta
from pathlib import Path

import numpy as np

from onebit.core.writers import write_text

#: True positions (m) of the home's sensors.
LAYOUT: dict[str, tuple[float, float]] = {
    **{f"M{k + 1:03d}": (3.0 * k + 1.5, 2.0) for k in range(8)},
    "M009": (13.5, 5.0),
    "M010": (13.5, 8.0),
    "D001": (0.0, 2.0),
    "D002": (22.5, 2.0),
}
#: Hallway adjacency (the true sensor graph).
EDGES = [(f"M{k:03d}", f"M{k + 1:03d}") for k in range(1, 8)] + [
    ("M005", "M009"),
    ("M009", "M010"),
    ("D001", "M001"),
    ("M008", "D002"),
]
ZONE = 1.5  # m: a PIR sees the resident within this distance
START = datetime(2011, 6, 15, 8, 0, 0)


def _route(rng: np.random.Generator) -> list[str]:
    """One outing: in through the front door, a few destinations, out again."""
    hall = [f"M{k:03d}" for k in range(1, 9)]
    dest = ["M008", "M010", "M003", "M006", "M010", "M008"]
    path, here = ["D001", "M001"], 1
    for d in rng.choice(dest, size=3, replace=False):
        if d in ("M009", "M010"):
            steps = hall[here - 1 : 5] if here <= 5 else hall[4 : here - 1][::-1] or []
            path += steps[1:] if steps and steps[0] == path[-1] else steps
            path += ["M009", "M010", "M009", "M005"]
            here = 5
        else:
            k = int(d[1:])
            seq = hall[here - 1 : k] if k >= here else hall[k - 1 : here][::-1]
            path += seq[1:]
            here = k
    seq = hall[:here][::-1]
    path += seq[1:] + ["D001"]
    out = [path[0]]
    for n in path[1:]:
        if n != out[-1]:
            out.append(n)
    return out


def simulate_casas(seed: int = 0, *, outings: int = 3) -> list[tuple[float, str, str, str]]:
    """Events ``(t, sensor, value, annotation)`` in gateway order (t = seconds after START)."""
    rng = np.random.default_rng(seed)
    events: list[tuple[float, str, str, str]] = []
    t = 5.0
    for _ in range(outings):
        route = _route(rng)
        pts = np.array([LAYOUT[n] for n in route])
        speed = rng.uniform(0.8, 1.3)
        times = [t]
        for a, b in zip(pts[:-1], pts[1:]):
            times.append(times[-1] + float(np.hypot(*(b - a))) / speed + rng.uniform(0.0, 2.0))
        # dense samples of the walk (10 Hz), then each PIR's zone visits
        ts = np.arange(times[0], times[-1], 0.1)
        xy = np.c_[np.interp(ts, times, pts[:, 0]), np.interp(ts, times, pts[:, 1])]
        for sid, (sx, sy) in LAYOUT.items():
            if not sid.startswith("M"):
                continue
            inside = np.hypot(xy[:, 0] - sx, xy[:, 1] - sy) <= ZONE
            if not inside.any():
                continue
            edges = np.flatnonzero(np.diff(np.r_[0, inside.astype(np.int8), 0]))
            for a, b in zip(edges[::2], edges[1::2]):
                t_in, t_out = ts[a], ts[b - 1]
                events.append((t_in, sid, "ON", ""))
                k = t_in + rng.uniform(0.8, 1.4)
                while k < t_out:  # the PIR re-triggers while the resident moves under it
                    events.append((k, sid, "ON", ""))
                    k += rng.uniform(0.8, 1.4)
                events.append((t_out + rng.uniform(1.0, 2.5), sid, "OFF", ""))
        for door, label in (("D001", "Enter_Home"), ("D001", "Leave_Home")):
            at = times[0] if label == "Enter_Home" else times[-1]
            events.append((at, door, "OPEN", f"{label} begin"))
            events.append((at + rng.uniform(2.0, 4.0), door, "CLOSE", f"{label} end"))
        if "M008" in route:
            at = times[route.index("M008")] + 1.0
            events.append((at, "D002", "OPEN", ""))
            events.append((at + rng.uniform(3.0, 6.0), "D002", "CLOSE", ""))
        events.append((times[0] + 2.0, "L001", "ON", ""))
        events.append((times[-1] - 2.0, "L001", "OFF", ""))
        t = times[-1] + rng.uniform(90.0, 150.0)  # away, then back
    for m in np.arange(0.0, t, 60.0):
        events.append((float(m), "T001", f"{21.0 + rng.normal(0, 0.3):.1f}", ""))
    events.sort(key=lambda e: e[0])
    # gateway order: a few lines arrive late, so their stamps are up to 0.7 s out of order
    delay = np.where(rng.random(len(events)) < 0.15, rng.uniform(0.0, 0.7, len(events)), 0.0)
    order = np.argsort(np.array([e[0] for e in events]) + delay, kind="stable")
    return [events[i] for i in order]


def casas_text(events: list[tuple[float, str, str, str]]) -> str:
    """The log's text (tabs between fields; the annotation only where there is one)."""
    out = []
    for t, sensor, value, note in events:
        stamp = (START + timedelta(seconds=float(t))).strftime("%Y-%m-%d %H:%M:%S.%f")
        out.append("\t".join([stamp, sensor, value] + ([note] if note else [])))
    return "\n".join(out) + "\n"


def write_casas_log(path: str | Path, *, seed: int = 0, outings: int = 3) -> Path:
    """Write the log (atomically) and return its path."""
    path = Path(path)
    write_text(casas_text(simulate_casas(seed, outings=outings)), path)
    return path
