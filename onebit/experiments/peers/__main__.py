"""``python -m onebit.experiments.peers DATASET [--jpda]``: the Stone Soup peer's scores on one
imported ceiling dataset (:func:`onebit.experiments.peers.stonesoup.main`)."""

import sys

from onebit.experiments.peers.stonesoup import main

sys.exit(main())
