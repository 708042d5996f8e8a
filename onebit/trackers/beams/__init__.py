"""Tracker ``beams``: region-graph agent assignment from directional beams (Bobadilla et al.)."""

from onebit.trackers.beams.assignment import Assignment, assign_agents, is_consistent_partition, minimum_agents
from onebit.trackers.beams.stage import SPEC, BeamsConfig, occupancy, run

__all__ = [
    "SPEC",
    "Assignment",
    "BeamsConfig",
    "assign_agents",
    "is_consistent_partition",
    "minimum_agents",
    "occupancy",
    "run",
]
