"""Trackers, one subpackage per paper. Importing :func:`load_trackers` registers them all."""

from __future__ import annotations

import importlib

#: Tracker packages, in the order their stages run.
TRACKER_MODULES: tuple[str, ...] = (
    "onebit.trackers.beams",
    "onebit.trackers.intruder",
    "onebit.trackers.clustertrack",
    "onebit.trackers.findinghumo",
    "onebit.trackers.istate",
)


def load_trackers() -> dict:
    from onebit.trackers.base import REGISTRY

    for mod in TRACKER_MODULES:
        importlib.import_module(mod)
    return REGISTRY
