"""O'Kane's set-based I-state filter (``istate`` tracker) and active tracking (section VII)."""

from onebit.trackers.istate.stage import SPEC, IStateConfig, run

__all__ = ["SPEC", "IStateConfig", "run"]
