"""Tracker ``binpf`` (beyond the papers): several people under an array of binary sensors,
by a labelled multi-Bernoulli particle filter with the soft-footprint noisy-OR likelihood."""

from onebit.trackers.binpf.filter import FilterParams, FilterResult, run_filter
from onebit.trackers.binpf.stage import SPEC, BinPFConfig, run

__all__ = ["SPEC", "BinPFConfig", "FilterParams", "FilterResult", "run", "run_filter"]
