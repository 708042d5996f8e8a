"""Trackers ``intruder`` and ``intruder-naive``: PIR intruder tracking (Schiff & Goldberg)."""

from onebit.trackers.intruder.filter import run_filter, sensor_likelihood
from onebit.trackers.intruder.sensors import Deployment, SensorType, deploy, sensor_type
from onebit.trackers.intruder.stage import IntruderConfig, NaiveConfig, run, run_naive

__all__ = [
    "Deployment",
    "IntruderConfig",
    "NaiveConfig",
    "SensorType",
    "deploy",
    "run",
    "run_filter",
    "run_naive",
    "sensor_likelihood",
    "sensor_type",
]
