"""FindingHuMo (De et al.): Adaptive-HMM + CPDA on a PIR sensor graph, and the hmm1 / hmm2 baselines."""

from onebit.trackers.findinghumo import stage  # noqa: F401  (registers findinghumo, hmm1, hmm2)
