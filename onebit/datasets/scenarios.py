"""Registry of simulated scenarios behind ``onebit simulate SCENARIO DIR``.

Each simulator module listed in :data:`SCENARIO_MODULES` defines ``SCENARIOS``: a dict of
:class:`Scenario`. A scenario's ``write(dataset, *, seed, duration, agents, drop, camera,
params)`` writes a complete dataset folder (``site.toml``, raw logs, ``truth.csv``) and
returns its path. ``agents`` is ``None`` for the scenario's default count; ``params`` holds
the scenario-specific ``--param key=value`` options as strings.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from onebit.errors import ConfigError

SCENARIO_MODULES: tuple[str, ...] = (
    "onebit.datasets.beams_sim",
    "onebit.datasets.pir_sim",
    "onebit.datasets.proximity_sim",
    "onebit.datasets.hallway_sim",
    "onebit.datasets.okane_sim",
)


@dataclass(frozen=True)
class Scenario:
    name: str
    help: str
    write: Callable[..., Path]


def all_scenarios() -> dict[str, Scenario]:
    out: dict[str, Scenario] = {}
    for mod in SCENARIO_MODULES:
        for name, sc in importlib.import_module(mod).SCENARIO_SPECS.items():
            out[name] = sc
    return out


def get_scenario(name: str) -> Scenario:
    known = all_scenarios()
    if name not in known:
        raise ConfigError(f"unknown scenario {name!r}; known: {sorted(known)}")
    return known[name]


def parse_params(items: list[str] | None) -> dict[str, str]:
    """``["k=v", ...]`` -> dict, naming the bad item."""
    out: dict[str, str] = {}
    for it in items or []:
        if "=" not in it:
            raise ConfigError(f"--param {it!r}: expected key=value")
        k, v = it.split("=", 1)
        out[k.strip()] = v.strip()
    return out
