"""How a tracker is drawn: its *look* (family, colour, error unit), declared on its pipeline entry.

A *family* is one paper's way of looking at a run: the ``beams`` family is Bobadilla et al.'s
agents in regions, ``intruder`` Schiff & Goldberg's particle filter (with its room-centre
baseline), ``clustertrack`` Singh et al.'s space-time view, ``findinghumo`` De et al.'s sensor
graph (with the ``hmm1`` / ``hmm2`` baselines) and ``istate`` O'Kane's I-states. The
blueprint (:mod:`onebit.viz.blueprint`) builds one tab per family, or per tracker where the
trackers of a family are alternatives to compare side by side (the HMM decoders).

Each tracker's :class:`Look` is a field of its ``TrackerEntry`` (``onebit.pipeline.stages``,
the one place a tracker is declared); the error unit comes from the entry's MOT gate (a gate
in hops: the error plot shows ``hop_error``). The pipeline passes the looks down to the viz
functions; a tracker with no look (the default :data:`GENERIC`) gets the generic layout: its
root in a site view, its error in a plot in the site's units, a palette colour from its name.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass


@dataclass(frozen=True)
class Look:
    """How one tracker is drawn.

    family : the blueprint tab it belongs to (one of :data:`FAMILY_ORDER`); ``None`` = the
        generic layout.
    rgb : its colour: its estimates, trails, boxes and error series are drawn in shades of it
        (truth is always neutral, :data:`onebit.viz.colors.TRUTH`); chosen apart from the
        sensor-state colours (red firing, orange refractory) and from the other trackers'.
        ``None`` = a palette colour from its name.
    hops : its error plot shows ``hop_error`` in hops (region and graph trackers, the papers'
        unit), else ``error`` in the site's units. Set from the tracker's MOT gate.
    """

    family: str | None = None
    rgb: tuple[int, int, int] | None = None
    hops: bool = False

    def __post_init__(self) -> None:
        if self.family is not None and self.family not in FAMILY_ORDER:
            raise ValueError(f"Look.family = {self.family!r}; known families: {list(FAMILY_ORDER)}")
        if self.rgb is not None and (len(self.rgb) != 3 or not all(0 <= int(c) <= 255 for c in self.rgb)):
            raise ValueError(f"Look.rgb = {self.rgb!r}; three integers in [0, 255]")


#: The look of a tracker that declares none.
GENERIC = Look()

#: Families in the order of their tabs; the first present is the tab a run opens on. Each has a
#: layout method of the same name in :class:`onebit.viz.blueprint.Planner`.
FAMILY_ORDER: tuple[str, ...] = ("beams", "clustertrack", "findinghumo", "intruder", "istate", "residents", "binpf")


def look_of(looks: Mapping[str, Look] | None, tracker: str) -> Look:
    """The look of ``tracker`` in ``looks`` (:data:`GENERIC` when it has none)."""
    return (looks or {}).get(tracker, GENERIC)


def family(tracker: str, looks: Mapping[str, Look] | None) -> str | None:
    """Family of ``tracker`` or ``None`` for a tracker without one."""
    return look_of(looks, tracker).family


def error_column(look: Look) -> str:
    """``"hop_error"`` for the region and graph trackers, else ``"error"`` (site units)."""
    return "hop_error" if look.hops else "error"


def error_unit(look: Look, site_units: str) -> str:
    """The unit of a tracker's error plot: ``"hops"`` or the site's length unit."""
    return "hops" if look.hops else site_units
