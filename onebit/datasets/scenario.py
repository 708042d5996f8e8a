"""What a simulated scenario is (``onebit simulate SCENARIO DIR``).

Each simulator module defines ``SCENARIO_SPECS``: a dict of :class:`Scenario`; the catalogue
:mod:`onebit.datasets.catalogue` lists them all. A scenario's ``write(dataset, *, seed, duration, agents, drop, camera,
params)`` writes a complete dataset folder (``site.toml``, raw logs, ``truth.csv``) and
returns its path. ``agents`` is ``None`` for the scenario's default count; ``params`` holds
the scenario-specific ``--param key=value`` options as strings.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from onebit.core.errors import ConfigError

@dataclass(frozen=True)
class Scenario:
    name: str
    help: str
    write: Callable[..., Path]


def parse_params(items: list[str] | None) -> dict[str, str]:
    """``["k=v", ...]`` -> dict, naming the bad item."""
    out: dict[str, str] = {}
    for it in items or []:
        if "=" not in it:
            raise ConfigError(f"--param {it!r}: expected key=value")
        k, v = it.split("=", 1)
        out[k.strip()] = v.strip()
    return out
