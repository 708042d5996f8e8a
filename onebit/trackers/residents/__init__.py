"""``residents``: who is who at home (:mod:`onebit.trackers.residents.stage`)."""

from onebit.trackers.residents.stage import NAME, SPEC, ResidentsConfig, run

__all__ = ["NAME", "SPEC", "ResidentsConfig", "run"]
