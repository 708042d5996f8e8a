"""``findinghumo-flow``: the sensor-graph HMM's paths cut at every co-location and joined over
the whole run by a minimum-cost flow (beyond the FindingHuMo paper, issue #15)."""

from onebit.trackers.findinghumo_flow.stage import SPEC, FlowConfig, run_flow

__all__ = ["SPEC", "FlowConfig", "run_flow"]
