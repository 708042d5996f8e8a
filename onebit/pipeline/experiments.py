"""Registry of the papers' studies behind ``onebit experiment NAME OUT``.

Each module in :data:`EXPERIMENT_MODULES` (name -> module) defines
``run(out: Path, *, seed: int, trials: int | None, quick: bool, echo) -> Path``: it simulates
the paper's scenarios, runs the trackers, and writes a polars table (``results.parquet`` and
``results.csv``) plus PNG plots into ``out``; it returns ``out``. ``trials=None`` means the
paper's number of trials; ``quick`` a reduced study for smoke tests.
"""

from __future__ import annotations

import importlib

from onebit.errors import ConfigError

EXPERIMENT_MODULES: dict[str, str] = {
    "singh": "onebit.pipeline.exp_singh",
    "schiff": "onebit.pipeline.exp_schiff",
    "okane": "onebit.pipeline.exp_okane",
}


def get_experiment(name: str):
    if name not in EXPERIMENT_MODULES:
        raise ConfigError(f"unknown experiment {name!r}; known: {sorted(EXPERIMENT_MODULES)}")
    return importlib.import_module(EXPERIMENT_MODULES[name])
