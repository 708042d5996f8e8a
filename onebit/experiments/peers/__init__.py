"""Peers: trackers from other libraries that the experiments score beside onebit's.

Each peer is an optional extra: its module imports the library only when it runs and has a
``missing()`` that names the extra to install when the library is absent, so an experiment
skips that peer's rows with the reason and runs the rest.

- :mod:`onebit.experiments.peers.stonesoup`: Stone Soup GNN and JPDA Kalman trackers fed every
  firing sensor as a point detection (``pip install 'onebit[bench]'``).
"""
