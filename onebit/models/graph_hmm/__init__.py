"""The HMM of users walking on a binary-sensor graph (FindingHuMo, De et al., section III-B):
the EATG (``eatg``), Viterbi decoders (``viterbi`` and their compiled ``kernels``), the
Adaptive-HMM window decoder (``adaptive``) and the slotting / user-count / tracks helpers
shared by the trackers that decode with it (``decoding``). Shared here, below the trackers,
so that ``findinghumo`` (+ CPDA) and ``findinghumo-flow`` (+ global association) both use it
without importing one another."""
