"""What a simulated scenario is (``onebit simulate SCENARIO DIR``).

Each simulator module defines ``SCENARIO_SPECS``: a dict of :class:`Scenario`; the catalogue
:mod:`onebit.datasets.catalogue` lists them all. A scenario's ``write(dataset, *, seed, duration, agents, drop, camera,
params)`` writes a complete dataset folder (``site.toml``, raw logs, ``truth.csv``) and
returns its path. ``agents`` is ``None`` for the scenario's default count; ``params`` holds
the scenario-specific ``--param key=value`` options as strings.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from onebit.core import writers
from onebit.core.errors import ConfigError, InputError

#: Marker file of a dataset folder written by :func:`simulate_into`.
MARKER = ".onebit-dataset"
#: Files a simulator writes; a folder holding only these (e.g. simulated before the marker
#: existed) also counts as written by onebit.
SIMULATED_FILES = frozenset(
    {
        "site.toml",
        "run.toml",
        "beams.csv",
        "crossings.csv",
        "truth.csv",
        "truth_crossings.csv",
        "truth_firings.csv",
        "motion.csv",
        "proximity.csv",
        "camera.mp4",
        "recording.mcap",
        MARKER,
        writers.INCOMPLETE,
    }
)


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


def check_simulation_args(*, seed, duration, agents, drop) -> None:
    """The common ``onebit simulate`` options: a seed >= 0, a finite duration > 0 (or the
    scenario's), agents >= 1 (or the scenario's), a drop probability in [0, 1]."""
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ConfigError(f"--seed {seed!r}: must be an integer >= 0")
    if duration is not None and (
        isinstance(duration, bool)
        or not isinstance(duration, (int, float))
        or not math.isfinite(duration)
        or duration <= 0
    ):
        raise ConfigError(f"--duration {duration!r}: must be a finite number of seconds > 0")
    if agents is not None and (isinstance(agents, bool) or not isinstance(agents, int) or agents < 1):
        raise ConfigError(f"--agents {agents!r}: must be an integer >= 1")
    if drop is not None and (isinstance(drop, bool) or not isinstance(drop, (int, float)) or not 0.0 <= drop <= 1.0):
        raise ConfigError(f"--drop {drop!r}: must be a probability in [0, 1]")


def check_dataset_target(dataset: str | Path) -> None:
    """``dataset`` may receive a simulation: absent, empty, or a folder onebit simulated into
    (the marker :data:`MARKER`, or only :data:`SIMULATED_FILES`); anything else is refused
    naming what is there, so a simulation never overwrites or mixes with other files."""
    dataset = Path(dataset)
    if dataset.exists() and not dataset.is_dir():
        raise InputError("exists and is not a folder; give a folder for the dataset", file=dataset)
    if not dataset.is_dir():
        return
    names = sorted(
        p.name for p in dataset.iterdir() if not p.name.startswith((writers.WORK_PREFIX, writers.OLD_PREFIX))
    )
    if not names or MARKER in names or set(names) <= SIMULATED_FILES:
        return
    foreign = [n for n in names if n not in SIMULATED_FILES]
    shown = ", ".join(foreign[:5]) + (f" and {len(foreign) - 5} more" if len(foreign) > 5 else "")
    raise InputError(
        f"not empty and not a dataset written by 'onebit simulate' (it holds {shown}); give an empty or new folder",
        file=dataset,
    )


def simulate_into(
    scenario: Scenario, dataset: str | Path, *, seed: int, duration, agents, drop: float, camera: bool, params: dict
) -> Path:
    """Write ``scenario`` into the folder ``dataset``, replacing it whole as one transaction
    (:func:`onebit.core.writers.folder_transaction`): the folder ends up holding exactly the
    new dataset (no stale ``camera.mp4`` or ``beams.csv`` of an earlier one), or, if the
    simulation fails or is killed, what it held before. Refuses a folder onebit did not write
    (:func:`check_dataset_target`) and bad options (:func:`check_simulation_args`)."""
    check_simulation_args(seed=seed, duration=duration, agents=agents, drop=drop)
    dataset = Path(dataset)
    check_dataset_target(dataset)
    with writers.folder_transaction(dataset) as work:
        scenario.write(work, seed=seed, duration=duration, agents=agents, drop=drop, camera=camera, params=params)
        writers.write_text(
            f'# written by onebit simulate\nscenario = "{scenario.name}"\nseed = {seed}\n', work / MARKER
        )
    return dataset
