"""``python -m benchmarks.stonesoup_ceiling DATASET [--jpda]``: the Stone Soup peer on one dataset.

The peer lives in the package (:mod:`onebit.experiments.peers.stonesoup`, the ``bench`` extra);
this command is kept for the benchmarks and runs the package's.
"""

from __future__ import annotations

import sys

from onebit.experiments.peers.stonesoup import StoneSoupConfig, detections_of, main, missing, track

__all__ = ["StoneSoupConfig", "detections_of", "main", "missing", "track"]

if __name__ == "__main__":
    sys.exit(main())
