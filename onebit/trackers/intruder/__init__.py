"""Trackers ``intruder`` and ``intruder-naive``: PIR intruder tracking (Schiff & Goldberg)."""

from onebit.trackers.intruder.filter import run_filter
from onebit.trackers.intruder.stage import NAIVE_SPEC, SPEC, IntruderConfig, NaiveConfig, run, run_naive

__all__ = ["NAIVE_SPEC", "SPEC", "IntruderConfig", "NaiveConfig", "run", "run_filter", "run_naive"]
