"""Scoring of the ``residents`` tracker.

Rows: the people it decoded (``people_decoded``) and, when the run has position truth and the
site a sensor graph, the hop error of its tracks against the true users' nodes, matched one to
one over the whole run (the HMM trackers' scoring, :func:`onebit.scoring.findinghumo.score`,
with its ``<tracker>_scores`` table). Per-event identity (which person each motion event was
attributed to, ``<tracker>_events``) is scored against an identity truth table where a
dataset has one (CASAS resident annotations; docs/metrics.md).
"""

from __future__ import annotations

from onebit.core.site import Site
from onebit.scoring import findinghumo


def score(name: str, tables: dict, site: Site, region_graph=None):
    """Report rows and ``<name>_scores`` (SCORES) for the residents tracker."""
    rows: list[tuple[str, str, float, str]] = []
    dec = tables.get(f"{name}_decoder")
    if dec is not None and dec.height:
        rows.append((name, "people_decoded", float(dec["people"][0]), "people"))
        rows.append((name, "events_attributed", float(dec["events"][0]), "events"))
    if site.sensor_graph is None or not site.sensor_graph.nodes:
        return rows, {}
    own = {k: v for k, v in tables.items() if k != f"{name}_decoder"}  # no HMM slots here
    more, out = findinghumo.score(name, own, site, region_graph)
    return rows + more, out
