"""onebit: tracking people, animals and robots from one-bit sensors.

Data flows one way: ``readers`` -> canonical polars tables -> ``trackers`` -> tracks ->
scores -> reports, with ``viz`` writing every stage's output to Rerun recordings.
"""

__version__ = "0.1.0"
