"""O'Kane's set-based I-state filter (``istate`` tracker) and active tracking (section VII)."""

from onebit.trackers.istate.stage import SPEC, IStateConfig  # noqa: F401 -- registers the tracker
