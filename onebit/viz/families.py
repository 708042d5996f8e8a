"""Which paper each tracker belongs to, its colour and the unit its error is shown in.

A *family* is one paper's way of looking at a run: the ``beams`` family is Bobadilla et al.'s
agents in regions, ``intruder`` Schiff & Goldberg's particle filter (with its room-centre
baseline), ``clustertrack`` Singh et al.'s space-time view, ``findinghumo`` De et al.'s sensor
graph (with the ``hmm1`` / ``hmm2`` baselines) and ``istate`` O'Kane's I-states. The
blueprint (:mod:`onebit.viz.blueprint`) builds one tab per family, or per tracker where the
trackers of a family are alternatives to compare side by side (the HMM decoders).

A tracker that is not listed here (a new one, ``docs/extending.md``) gets the generic
layout: its root in a site view and its error in a plot, in the site's units.
"""

from __future__ import annotations

#: Family of every tracker the pipeline declares (``onebit.pipeline.stages.TRACKERS``).
FAMILY_OF: dict[str, str] = {
    "beams": "beams",
    "intruder": "intruder",
    "intruder-naive": "intruder",
    "clustertrack": "clustertrack",
    "findinghumo": "findinghumo",
    "hmm1": "findinghumo",
    "hmm2": "findinghumo",
    "findinghumo-flow": "findinghumo",
    "istate": "istate",
    "residents": "residents",
    "binpf": "binpf",
}

#: Families in the order of their tabs; the first present is the tab a run opens on.
FAMILY_ORDER: tuple[str, ...] = ("beams", "clustertrack", "findinghumo", "intruder", "istate", "residents", "binpf")

#: Each tracker's colour (RGB): its estimates, trails, boxes and error series are drawn in
#: shades of it; truth is always neutral (:data:`onebit.viz.colors.TRUTH`). Chosen apart from
#: the sensor-state colours (red firing, orange refractory) and from each other.
TRACKER_RGB: dict[str, tuple[int, int, int]] = {
    "beams": (64, 196, 255),
    "intruder": (70, 225, 110),
    "intruder-naive": (200, 120, 255),
    "clustertrack": (255, 160, 40),
    "findinghumo": (255, 200, 60),
    "hmm1": (90, 200, 255),
    "hmm2": (240, 110, 200),
    "findinghumo-flow": (120, 240, 200),
    "istate": (255, 235, 130),
    "residents": (255, 140, 120),
    "binpf": (255, 110, 90),
    "camera": (165, 165, 165),
}

#: Score column (``SCORES``) and unit of each tracker's error plot; every other tracker shows
#: ``error`` in the site's units. Region and graph trackers are scored in hops, the papers' unit.
HOP_TRACKERS: frozenset[str] = frozenset({"beams", "findinghumo", "hmm1", "hmm2", "findinghumo-flow"})


def family(tracker: str) -> str | None:
    """Family of ``tracker`` or ``None`` for a tracker this module does not know."""
    return FAMILY_OF.get(tracker)


def error_column(tracker: str) -> str:
    """``"hop_error"`` for the region and graph trackers, else ``"error"`` (site units)."""
    return "hop_error" if tracker in HOP_TRACKERS else "error"


def error_unit(tracker: str, site_units: str) -> str:
    """The unit of ``tracker``'s error plot: ``"hops"`` or the site's length unit."""
    return "hops" if tracker in HOP_TRACKERS else site_units
