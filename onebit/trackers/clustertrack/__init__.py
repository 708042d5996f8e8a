"""CLUSTERTRACK (Singh et al. 2011): target counting and multi-target tracking from binary
proximity sensors, in 1-D (exact intervals) and 2-D (raster)."""

from onebit.trackers.clustertrack.stage import SPEC, ClusterTrackConfig, run

__all__ = ["SPEC", "ClusterTrackConfig", "run"]
