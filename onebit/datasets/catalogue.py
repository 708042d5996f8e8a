"""Every simulated scenario, by name (``onebit simulate list``).

Adding a simulator: give its module ``SCENARIO_SPECS`` and list it here.
"""

from __future__ import annotations

from onebit.core.errors import ConfigError
from onebit.datasets import (
    beams_sim,
    building_sim,
    from_truth,
    hallway_sim,
    home_sim,
    okane_sim,
    pir_sim,
    proximity_sim,
)
from onebit.datasets.scenario import Scenario

SCENARIOS: dict[str, Scenario] = {
    **beams_sim.SCENARIO_SPECS,
    **pir_sim.SCENARIO_SPECS,
    **proximity_sim.SCENARIO_SPECS,
    **hallway_sim.SCENARIO_SPECS,
    **home_sim.SCENARIO_SPECS,
    **okane_sim.SCENARIO_SPECS,
    **from_truth.SCENARIO_SPECS,
    **building_sim.SCENARIO_SPECS,
}

#: Scenarios that add logs to an existing dataset folder (its site.toml and truth.csv) instead
#: of writing a new one: ``onebit simulate`` calls them on the folder itself.
IN_PLACE = frozenset({from_truth.NAME})


def all_scenarios() -> dict[str, Scenario]:
    return dict(SCENARIOS)


def get_scenario(name: str) -> Scenario:
    if name not in SCENARIOS:
        raise ConfigError(f"unknown scenario {name!r}; known: {sorted(SCENARIOS)}")
    return SCENARIOS[name]
