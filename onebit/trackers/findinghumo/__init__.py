"""FindingHuMo (De et al.): Adaptive-HMM + CPDA on a PIR sensor graph, and the hmm1 / hmm2 baselines."""

from onebit.trackers.findinghumo.stage import SPECS, FindingHumoConfig, HmmConfig, run_findinghumo, run_hmm1, run_hmm2

__all__ = ["SPECS", "FindingHumoConfig", "HmmConfig", "run_findinghumo", "run_hmm1", "run_hmm2"]
