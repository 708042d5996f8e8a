"""The papers' studies behind ``onebit experiment NAME OUT``.

Each module in :data:`EXPERIMENTS` (name -> module) defines
``run(out: Path, *, seed: int, trials: int | None, quick: bool, echo) -> Path``: it simulates
the paper's scenarios, runs the trackers, and writes a polars table (``results.parquet`` and
``results.csv``) plus PNG plots into ``out``; it returns ``out``. ``trials=None`` means the
paper's number of trials; ``quick`` a reduced study for smoke tests.
"""

from __future__ import annotations

from types import ModuleType

from onebit.core.errors import ConfigError
from onebit.experiments import okane, schiff, singh

EXPERIMENTS: dict[str, ModuleType] = {"singh": singh, "schiff": schiff, "okane": okane}


def get_experiment(name: str) -> ModuleType:
    if name not in EXPERIMENTS:
        raise ConfigError(f"unknown experiment {name!r}; known: {sorted(EXPERIMENTS)}")
    return EXPERIMENTS[name]
