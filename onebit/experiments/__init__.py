"""The papers' studies behind ``onebit experiment NAME OUT``.

Each module in :data:`EXPERIMENTS` (name -> module) defines
``run(out: Path, *, seed: int, trials: int | None, quick: bool, echo, executor) -> Path``: it
simulates the paper's scenarios, runs the trackers, and writes a polars table
(``results.parquet`` and ``results.csv``), ``timings.csv`` and, for some, PNG plots into
``out``; it returns ``out``. ``trials=None`` means the paper's number of trials (or seeds);
``quick`` a reduced study for smoke tests; ``executor`` (:mod:`onebit.pipeline.executors`,
default serial) runs the trials as independent tasks -- in this process, a local process
pool or Ray -- with the same tables on every executor (:mod:`onebit.experiments.trials`).

``correct`` and ``findinghumo`` are the seed sweeps of ``docs/beams-correct.md`` and
``docs/findinghumo.md``: they run the whole pipeline per seed; ``residents`` reads a folder of
real CASAS sessions instead (``onebit experiment residents DIR``, :mod:`onebit.experiments.residents`); ``findinghumo-diagnose`` lists
every identity swap of the HMM trackers over 20 seeds (the diagnosis table of that note).
``ceiling`` runs every positional tracker and the baselines on the real ceiling array of
Milan et al. (``--data DIR``: the irtracking recordings; :mod:`onebit.experiments.ceiling`).
"""

from __future__ import annotations

from types import ModuleType

from onebit.core.errors import ConfigError
from onebit.experiments import (
    ceiling,
    correct,
    findinghumo,
    findinghumo_diagnose,
    homes,
    okane,
    residents,
    schiff,
    singh,
)

EXPERIMENTS: dict[str, ModuleType] = {
    "singh": singh,
    "schiff": schiff,
    "okane": okane,
    "correct": correct,
    "findinghumo": findinghumo,
    "findinghumo-diagnose": findinghumo_diagnose,
    "residents": residents,
    "ceiling": ceiling,
    "homes": homes,
}


def get_experiment(name: str) -> ModuleType:
    if name not in EXPERIMENTS:
        raise ConfigError(f"unknown experiment {name!r}; known: {sorted(EXPERIMENTS)}")
    return EXPERIMENTS[name]
