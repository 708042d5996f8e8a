"""Trackers, one subpackage per paper: pure batch functions ``tables + site -> tracks``.

The pipeline's stage list (:mod:`onebit.pipeline.stages`) names every tracker; nothing is
registered here.
"""
