"""The viewer layout of a run: one tab per tracker family, made from what the run logged.

:func:`save_run_blueprint` reads back every ``OUT/rrd/*.rrd`` of a finished run (entity paths
and their archetypes, :func:`onebit.viz.inspect.entity_archetypes`), builds the layout with
:func:`make_blueprint` and writes it to ``OUT/rrd/blueprint.rbl``; ``rerun OUT/rrd/*`` opens the
recordings and the blueprint together (``docs/viewing.md``); the same blueprint is sent with
the run in ``OUT/rrd/_blueprint.rrd``, so ``rerun OUT/rrd/*.rrd`` opens on it too.

Each tab opens on what its paper is about (:mod:`onebit.viz.families`):

* **beams** -- the site with regions and beams (a beam flashes when crossed), each agent's
  current region outlined and its recent moves, truth as hollow rings; agents per region; the
  region error in hops; the crossing log (observed, assigned, ambiguous, unexplained, inserted);
* **clustertrack** -- the space-time diagram (1-D: position right, time up, labelled axes,
  feasible space, tracks, truth, a line at the current instant) with the counting bound and the
  error over time, and the line at the current instant (sensors, F, particles, tracks);
* **findinghumo** (and each HMM baseline in its own tab) -- the sensor graph with the active
  nodes of the slot and each decoded track with its trail; hop error per track; sensor states;
* **intruder** -- the room with every sensor's field of view dimmed and the firing ones
  highlighted, particles by weight, the estimate (and the room-centre baseline) against the
  truth; distance from the truth; sensor states;
* **istate** -- the I-state's elements filled and outlined over the site with the sensing
  regions reading 1 now and the true positions (all sensing regions and the point summaries'
  trails hidden);
  element count, area and error;
* **residents** -- each person at the sensor of their latest event with their trail, every
  motion event in the colour of the person it was given to; error per track (where there is
  truth); the people present; sensor states.

When the ``occupancy`` stage ran there is a **home** tab (:meth:`Planner.home`): the site with
each motion sensor labelled and lit while on, each resident's estimated place; the people home
against the truth with the door events, as steps over the whole run (time axis and visible range
unbounded, not the window at the cursor); the sensors' states. A run of home trackers only
(``residents``) opens on it; otherwise it follows the trackers' tabs.

Every run with a tracker (or a home) has a **summary** tab, the last (:meth:`Planner.summary`):
the people present by every tracker (``<tracker>/people``) and the count model against the
truth, each tracker's error, the sensors' on / off bands and the crossing log; its plots and
band span the whole run, as the home tab's count.

Views that would be empty are not created and every view names only logged entities (exact
paths). Every logged entity is in some view: what no family shows goes to a last tab, "more".
Trails (``.../trail``) get a visible time range ``[cursor - trail_s, cursor]``; whole paths,
heat maps, the camera's tracks and the 2-hop EATG edges are in their views but hidden (tick
their eye in the blueprint panel); one-off events (a crossed beam, an inserted or ambiguous
crossing, a CPDA decision) stay visible for a short window after their time (``FLASH_S``, ``DECISION_S``).

Stage recordings carry no blueprint of their own (it depends on what every stage logged): the
one layout is written once the stages are done, as ``blueprint.rbl`` and, sent with the run, as
``_blueprint.rrd`` (:data:`BLUEPRINT_RECORDING`).
"""

from __future__ import annotations

import functools
from collections.abc import Iterable, Mapping
from pathlib import Path

from onebit.core import writers
from onebit.core.lazy import lazy_module
from onebit.viz import colors, paths
from onebit.viz.families import FAMILY_ORDER, Look, error_unit, family, look_of
from onebit.viz.inspect import entity_archetypes, scalar_ranges, store_ids
from onebit.viz.recording import APPLICATION_ID, close_recording, open_recording
from onebit.viz.tracks import natural_key
from onebit.viz.trails import TRAIL_S

rr = lazy_module("rerun")
rrb = lazy_module("rerun.blueprint")

#: File name of the run's blueprint, next to the recordings.
BLUEPRINT_FILE = "blueprint.rbl"
#: The same blueprint sent in a recording of the run (same application and recording id, no
#: data), named to sort before every stage's file: a viewer that takes the layout from the
#: first file it opens (the viewer catalog of ``rrd-snapshot``) and ``rerun OUT/rrd/*.rrd`` both
#: open on it.
BLUEPRINT_RECORDING = "_blueprint.rrd"
#: How long a one-off event stays on the map after its time (s).
FLASH_S = 2.0
#: How long a decision label (a CPDA pairing, a flow join, a switch) stays on the map after its
#: slot (s): long enough to read, short enough that the labels of the next meetings along a
#: corridor do not pile up on it (at the 10 s trail window three overlapped, see docs/viewing.md).
DECISION_S = 3.0

SPATIAL = frozenset({"Points2D", "LineStrips2D", "Boxes2D", "Ellipses2D", "Arrows2D", "EncodedImage", "Image"})
FRAME = frozenset({"Transform3D"})
SERIES = frozenset({"Scalars"})
TEXT = frozenset({"TextLog"})
STATE = frozenset({"StateChange"})
#: Root of the ``occupancy`` stage (:mod:`onebit.viz.occupancy`): it gets the "home" tab.
HOME_ROOT = "occupancy"
#: Name of the home tab (``onebit snapshot RUN --view home``).
HOME_TAB = "home"
#: Error plots a row on the summary tab (one per tracker).
SUMMARY_COLUMNS = 3
#: Name of the summary tab (``onebit snapshot RUN --view summary``).
SUMMARY_TAB = "summary"
#: Root of the series only the summary tab shows (the true count of a run with tracked truth).
SUMMARY_ROOT = "summary"
#: Roots that are not a tracker's.
SHARED_ROOTS = frozenset(
    {paths.SITE, paths.TRUTH, paths.SENSORS, paths.SCORES, "camera", "correct", HOME_ROOT, SUMMARY_ROOT}
)


class Logged:
    """What a run's recordings hold: ``{entity path: archetype names}`` with small queries."""

    def __init__(
        self, archetypes: Mapping[str, Iterable[str]], ranges: Mapping[str, tuple[float, float]] | None = None
    ) -> None:
        self.kinds: dict[str, frozenset[str]] = {
            p.strip("/"): frozenset(a) for p, a in archetypes.items() if p.strip("/")
        }
        #: (min, max) of each Scalars entity, when known: count plots start at 0 and fit the largest value
        self.ranges: dict[str, tuple[float, float]] = {p.strip("/"): r for p, r in (ranges or {}).items()}

    def __contains__(self, path: str) -> bool:
        return path in self.kinds

    def under(self, prefix: str, kinds: frozenset[str] | None = None) -> list[str]:
        """``prefix`` and its descendants that were logged (with one of ``kinds``), in natural order."""
        out = [p for p in self.kinds if p == prefix or p.startswith(prefix + "/")]
        if kinds is not None:
            out = [p for p in out if self.kinds[p] & kinds]
        return sorted(out, key=natural_key)

    def roots(self) -> list[str]:
        return sorted({p.split("/")[0] for p in self.kinds}, key=natural_key)

    def frame(self, path: str) -> list[str]:
        """``[path]`` if ``path`` was logged (it carries the y-up frame), else ``[]``."""
        return [path] if path in self.kinds else []


class View:
    """A view being planned: its kind, title, exact entities, per-entity overrides and, for a
    time series of counts, its y range."""

    def __init__(
        self,
        kind: str,
        name: str,
        entities: Iterable[str],
        *,
        hidden: Iterable[str] = (),
        windows=None,
        y_range=None,
        shown: Mapping[str, list] | None = None,
        whole_run: bool = False,
    ) -> None:
        self.kind, self.name = kind, name
        self.entities = list(dict.fromkeys(entities))
        self.hidden = [h for h in dict.fromkeys(hidden) if h in self.entities]
        self.windows = {p: w for p, w in (windows or {}).items() if p in self.entities}
        self.y_range = y_range
        #: per-entity component overrides (e.g. labels shown), for entities in the view
        self.shown = {p: list(a) for p, a in (shown or {}).items() if p in self.entities}
        #: a time series that spans the whole run (both ends unbounded), not a window at the cursor
        self.whole_run = bool(whole_run)

    def shows_data(self, logged: Logged) -> bool:
        want = {"map": SPATIAL, "series": SERIES, "text": TEXT, "state": STATE}[self.kind]
        return any(logged.kinds.get(p, frozenset()) & want for p in self.entities)

    def build(self) -> rrb.View:
        contents = [f"+ {p}" for p in self.entities]
        overrides: dict[str, list] = {}
        for p in self.hidden:
            overrides.setdefault(p, []).append(rrb.EntityBehavior(visible=False))
        for p, archetypes in self.shown.items():
            overrides.setdefault(p, []).extend(archetypes)
        for p, seconds in self.windows.items():
            overrides.setdefault(p, []).append(
                rrb.VisibleTimeRanges(
                    [
                        rrb.VisibleTimeRange(
                            paths.TIMELINE,
                            start=rrb.TimeRangeBoundary.cursor_relative(seconds=-float(seconds)),
                            end=rrb.TimeRangeBoundary.cursor_relative(seconds=0.0),
                        )
                    ]
                )
            )
        if self.kind == "map":
            return rrb.Spatial2DView(
                name=self.name,
                origin="/",
                contents=contents,
                overrides=overrides or None,
                background=rrb.Background(kind=rrb.BackgroundKind.SolidColor, color=colors.MAP_BACKGROUND),
            )
        if self.kind == "series":
            axis = rrb.ScalarAxis(range=self.y_range) if self.y_range is not None else None
            return rrb.TimeSeriesView(
                name=self.name,
                origin="/",
                contents=contents,
                axis_y=axis,
                axis_x=whole_run_axis() if self.whole_run else None,
                time_ranges=whole_run_range() if self.whole_run else None,
                plot_legend=rrb.PlotLegend(rrb.Corner2D.LeftTop, visible=True),
            )
        if self.kind == "text":
            return rrb.TextLogView(name=self.name, origin="/", contents=contents)
        return rrb.StateTimelineView(
            name=self.name,
            origin="/",
            contents=contents,
            time_view=whole_run_axis() if self.whole_run else None,
            time_ranges=whole_run_range() if self.whole_run else None,
        )


def whole_run_range() -> rrb.VisibleTimeRange:
    """The visible time range of a plot that spans the whole run on :data:`paths.TIMELINE`."""
    return rrb.VisibleTimeRange(
        paths.TIMELINE, start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.infinite()
    )


def whole_run_axis() -> rrb.TimeAxis:
    """The time axis of a plot that shows the whole run (not the window around the cursor that
    the viewer shows by default), zoomed on its own."""
    every = rr.TimeRange(start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.infinite())
    return rrb.TimeAxis(link=rrb.components.LinkAxis.Independent, view_range=every)


class Planner:
    """Builds the tabs of one run from :class:`Logged`, recording which entities are placed."""

    def __init__(self, logged: Logged, *, units: str, trail_s: float, looks: Mapping[str, Look] | None = None) -> None:
        self.L, self.units, self.trail_s = logged, units, float(trail_s)
        self.looks = dict(looks or {})
        self.placed: set[str] = set()

    # ---------------------------------------------------------------- building blocks

    def view(self, kind: str, name: str, entities: Iterable[str], **kw) -> View | None:
        v = View(kind, name, entities, **kw)
        if not v.entities or not v.shows_data(self.L):
            return None
        self.placed.update(v.entities)
        return v

    def count_view(self, name: str, entities: list[str], **kw) -> View | None:
        """A time series of counts (agents, targets, elements, hops): y from 0 to a little
        above the largest value logged, so a constant count is not drawn on the plot's edge."""
        top = max((self.L.ranges[p][1] for p in entities if p in self.L.ranges), default=None)
        y_range = (0.0, float(top) * 1.1 + 0.5) if top is not None and top >= 0 else None
        return self.view("series", name, entities, y_range=y_range, **kw)

    def moving_overrides(self, entities: list[str]) -> tuple[list[str], dict[str, float]]:
        """Hidden whole paths and trail windows among ``entities`` (by their last path part)."""
        hidden = [p for p in entities if p.rsplit("/", 1)[-1] in ("path", "regions")]
        windows = {p: self.trail_s for p in entities if p.endswith("/trail")}
        return hidden, windows

    def site(self, *, coverage: bool = False) -> list[str]:
        """The site drawing: its root (frame), boundary, obstacles, beams, regions, free space,
        the sensors' dim marks; with ``coverage`` the sensors' heat maps (``site/sensors/<id>/coverage``)."""
        return [p for p in self.L.under(paths.SITE) if coverage or not p.endswith("/coverage")]

    def sensor_marks(self) -> list[str]:
        return self.L.frame(f"{paths.SITE}/sensors")

    def truth(self) -> list[str]:
        return self.L.under(paths.TRUTH)

    def states(self) -> list[str]:
        return self.L.under(paths.SENSORS, STATE)

    def scores(self, trackers: Iterable[str]) -> list[str]:
        return [p for t in trackers for p in self.L.under(paths.join(paths.SCORES, paths.part(t)), SERIES)]

    def error_view(self, trackers: list[str], what: str) -> View | None:
        unit = error_unit(look_of(self.looks, trackers[0]), self.units)
        if unit == "hops":
            return self.count_view(f"{what} ({unit})", self.scores(trackers))
        return self.view("series", f"{what} ({unit})", self.scores(trackers))

    def map_view(self, name: str, entities: list[str], *, hidden=(), windows=None, shown=None) -> View | None:
        h, w = self.moving_overrides(entities)
        return self.view("map", name, entities, hidden=[*h, *hidden], windows={**w, **(windows or {})}, shown=shown)

    def sensor_labels(self) -> dict[str, list]:
        """Overrides that show the sensors' ids on their marks (``site/sensors``), for the maps
        of home trackers where the sensors are few and the ids are what a reader looks for."""
        kinds = self.L.kinds.get(f"{paths.SITE}/sensors", frozenset())
        parts = [
            a.from_fields(show_labels=True)
            for name, a in (("Arrows2D", rr.Arrows2D), ("Points2D", rr.Points2D))
            if name in kinds
        ]
        return {f"{paths.SITE}/sensors": parts} if parts else {}

    def home(self, residents: list[str]) -> rrb.Container | None:
        """The home (the ``occupancy`` stage ran): the site with each motion sensor labelled
        and lit while on, each resident's estimated place with a short trail (the ``residents``
        trackers); the people home against the truth, with the door events, as steps over the
        whole run; the sensors' on / off bands."""
        if not self.L.under(HOME_ROOT):
            return None
        # the sensors are drawn lit and labelled by the home stage; a single region's name (a
        # house with no floor plan) would only cover a sensor's label
        regions = self.L.under(f"{paths.SITE}/regions")
        drop = {f"{paths.SITE}/sensors", *(regions if len(regions) == 1 else [])}
        site = [p for p in self.site() if p not in drop]
        people = [
            p
            for t in residents
            for p in [*self.L.frame(paths.tracker_root(t)), *self.L.under(paths.join(paths.tracker_root(t), "tracks"))]
        ]
        entities = [*site, *self.L.under(HOME_ROOT, SPATIAL | FRAME), *self.truth(), *people]
        where = self.map_view(f"home ({self.units}): sensors on (red), each resident's estimated place", entities)
        series = self.L.under(HOME_ROOT, SERIES)
        # the truth first, so the model's line is drawn over it
        series = sorted(series, key=lambda p: p != paths.join(HOME_ROOT, "truth"))
        count = self.count_view("people home: model vs truth, door events (count)", series, whole_run=True)
        if count is not None and count.y_range is not None:  # room for the door marks under 0
            count.y_range = (-0.5, count.y_range[1])
        states = self.view("state", "home: motion sensors on / off", self.states())
        return _tab(HOME_TAB, where, [count, states])

    def summary(self, trackers: list[str]) -> rrb.Container | None:
        """The run at a glance, every plot over the whole run (time axis and visible range
        unbounded): the people present by every tracker (``<tracker>/people``) and by the
        count model (``occupancy/present``) against the truth (``summary/truth`` from the
        tracked truth, ``occupancy/truth`` from a home's ``truth_count``), with the
        door events; the error of every tracker's tracks, one plot per tracker (in a grid); the
        run's events (the sensors' on / off bands, the crossing log)."""
        # the truths first, so the estimates' lines are drawn over them
        truths = [p for p in (paths.join(SUMMARY_ROOT, "truth"), paths.join(HOME_ROOT, "truth")) if p in self.L]
        home = [p for p in self.L.under(HOME_ROOT, SERIES) if p not in truths]
        people = [p for t in trackers for p in self.L.under(paths.join(paths.tracker_root(t), "people"), SERIES)]
        vs = " vs the truth" if truths else ""
        count = self.count_view(
            f"people present: each tracker{vs} over the run (count)", [*truths, *home, *people], whole_run=True
        )
        if count is not None and count.y_range is not None and paths.join(HOME_ROOT, "doors") in count.entities:
            count.y_range = (-0.5, count.y_range[1])  # room for the door marks under 0
        errors = []
        for t in trackers:  # one plot per tracker: the legends name tracks, not trackers
            unit = error_unit(look_of(self.looks, t), self.units)
            kind = self.count_view if unit == "hops" else functools.partial(self.view, "series")
            errors.append(kind(f"{t}: error of each track over the run ({unit})", self.scores([t]), whole_run=True))
        errors = [v for v in errors if v is not None]
        states = self.view("state", "events: sensors on / off over the run", self.states(), whole_run=True)
        log = self.view("text", "events: crossing log", self.L.under(paths.SENSORS, TEXT))
        if count is None and not errors:
            return None
        events = _row([states, log], shares=[3, 2]) if states is not None or log is not None else None
        # the error plots side by side, at most SUMMARY_COLUMNS a row
        grid = rrb.Grid(*_built(errors), grid_columns=min(len(errors), SUMMARY_COLUMNS)) if len(errors) > 1 else None
        parts = [count, grid if grid is not None else (errors[0] if errors else None), events]
        shares = [s for s, p in zip((2, 3 if len(errors) > SUMMARY_COLUMNS else 2, 2), parts) if p is not None]
        return _named(_column(parts, shares=shares), SUMMARY_TAB)

    # ---------------------------------------------------------------- families

    def beams(self, tracker: str) -> rrb.Container | None:
        root = paths.tracker_root(tracker)
        crossed = [p for p in self.L.under(paths.SENSORS, SPATIAL) if p.endswith("/crossed")]
        camera = self.L.under("camera")
        marks = [p for k in ("ambiguous", "unexplained") for p in self.L.frame(paths.join(root, k))]
        inserted = self.L.frame("correct/crossings/inserted")
        observed = self.L.frame("correct/crossings/observed")
        entities = [
            *self.site(),
            *self.L.frame(paths.SENSORS),
            *crossed,
            *self.truth(),
            *self.L.frame(root),
            *self.L.under(paths.join(root, "tracks")),
            *marks,
            *self.L.frame("correct"),
            *observed,
            *inserted,
            *camera,
        ]
        windows = {p: FLASH_S for p in crossed} | {p: self.trail_s for p in [*marks, *inserted]}
        site = self.map_view(
            f"regions, beams and agents ({self.units})", entities, hidden=[*camera, *observed], windows=windows
        )
        occupancy = self.count_view("agents per region (count)", self.L.under(paths.join(root, "occupancy"), SERIES))
        error = self.error_view([tracker], "error of each track: hops from its region to the true agent's")
        log = self.view(
            "text",
            "crossing log",
            [*self.L.under(paths.SENSORS, TEXT), *self.L.under(root, TEXT), *self.L.under("correct", TEXT)],
        )
        return _tab(f"{tracker}: agents in regions", site, [occupancy, error, log])

    def intruder(self, trackers: list[str]) -> rrb.Container | None:
        entities = [*self.site(coverage=True), *self.truth()]
        for t in trackers:
            entities += self.L.under(paths.tracker_root(t), SPATIAL | FRAME)
        coverage = [p for p in entities if p.startswith(f"{paths.SITE}/sensors/")]
        room = self.map_view(
            f"room ({self.units}): sensors firing, particles by weight, estimate vs truth", entities, hidden=coverage
        )
        error = self.error_view(trackers, "distance of the estimate from the truth")
        states = self.view("state", "motion sensors: on / off", self.states())
        return _tab(f"{trackers[0]}: particle filter", room, [error, states])

    def clustertrack(self, tracker: str) -> rrb.Container | None:
        root = paths.tracker_root(tracker)
        space_time = self.L.under(paths.join(root, "space_time"))
        count = self.count_view(
            "number of targets: counting bound vs truth (targets)", self.L.under(paths.join(root, "count"), SERIES)
        )
        error = self.error_view([tracker], "distance of each track from its target")
        now = [
            *self.site(),
            *self.truth(),
            *self.L.frame(root),
            *[
                p
                for p in self.L.under(root, SPATIAL | FRAME)
                if p != root and not p.startswith(paths.join(root, "space_time"))
            ],
        ]
        if space_time:
            diagram = self.map_view(
                f"space-time: position ({self.units}) to the right, time (s) up", [*self.L.frame(root), *space_time]
            )
            line = self.map_view(
                f"the line now ({self.units}): sensors on (red), feasible space (blue), particles, tracks", now
            )
            top = _row([diagram, _column([count, error])], shares=[3, 2])
            return _named(_column([top, line], shares=[3, 1]), f"{tracker}: space-time")
        site = self.map_view(f"site now ({self.units}): sensors, feasible space, particles, tracks", now)
        return _tab(f"{tracker}: feasible space", site, [count, error])

    def findinghumo(self, tracker: str) -> rrb.Container | None:
        root = paths.tracker_root(tracker)
        graph = [p for p in self.L.under(root, SPATIAL | FRAME)]
        hidden = [
            *self.L.under(paths.join(root, "decoded")),
            *self.L.frame(paths.join(root, "eatg", "a2")),
            # the HMM trackers draw the sensor graph's nodes themselves; residents draws no graph
            *(self.sensor_marks() if tracker != "residents" else []),
        ]
        windows = {
            p: min(DECISION_S, self.trail_s)
            for name in ("switches", "cpda", "joins", "joint")
            for p in self.L.frame(paths.join(root, name))
        }
        entities = [*self.site(), *self.truth(), *graph]
        what = {
            "findinghumo": "sensor graph, CPDA decisions",
            "findinghumo-flow": "sensor graph, flow joins",
            "residents": "people and the events attributed to them",
        }.get(tracker, "sensor graph, baseline decoder")
        site = self.map_view(
            f"{what} ({self.units}): active nodes, decoded tracks, truth",
            entities,
            hidden=hidden,
            windows=windows,
            shown=self.sensor_labels() if family(tracker, self.looks) == "residents" else None,
        )
        error = self.error_view([tracker], "hop error of each decoded track")
        states = self.view("state", "motion sensors: on / off", self.states())
        people = self.count_view("people present (count)", self.L.under(paths.join(root, "people"), SERIES))
        return _tab(f"{tracker}: decoded paths", site, [error, people, states])

    def residents(self, tracker: str) -> rrb.Container | None:
        """The residents tracker (beyond the papers): its people and attributed events over the
        site, as the sensor-graph trackers' tab shows theirs (plus the people present)."""
        return self.findinghumo(tracker)

    def binpf(self, tracker: str) -> rrb.Container | None:
        """The binary-array particle filter (beyond the papers): the sensors on, the particles
        and the people over the site; the estimated count against the truth; the error."""
        root = paths.tracker_root(tracker)
        entities = [*self.site(), *self.truth(), *self.L.under(root, SPATIAL | FRAME)]
        site = self.map_view(f"site now ({self.units}): sensors on, particles, people, truth", entities)
        count = self.count_view(
            "number of people: expected and reported (count)", self.L.under(paths.join(root, "count"), SERIES)
        )
        error = self.error_view([tracker], "distance of each person from their target")
        zones = self.L.under(paths.join(root, "zones", "count"), SERIES)
        if zones:  # a floor of hundreds of sensors: people per zone, not a row per sensor
            states = self.count_view("people per zone (reported tracks)", zones)
        else:
            states = self.view("state", "sensors: on / off", self.states())
        return _tab(f"{tracker}: people from the array", site, [count, error, states])

    def istate(self, tracker: str) -> rrb.Container | None:
        root = paths.tracker_root(tracker)
        entities = [*self.site(), *self.truth(), *self.L.under(root, SPATIAL | FRAME)]
        # the point summaries (scored, not the paper's object) jump between elements: no trail shown
        summary_trails = [p for p in self.L.under(paths.join(root, "tracks")) if p.endswith("/trail")]
        # every sensing region at once hides the elements (PIR wedges reach past the room): the
        # ones reading 1 now are drawn (detections), the rest can be ticked on
        sensing = self.L.under(paths.join(root, "sensing"))
        site = self.map_view(
            f"I-state over the site ({self.units}): elements, detections, true positions",
            entities,
            hidden=[*summary_trails, *sensing],
        )
        elements = self.count_view(
            "elements in the I-state (count)", self.L.under(paths.join(root, "elements"), SERIES)
        )
        area = self.view(
            "series", f"area of the I-state ({self.units}\u00b2)", self.L.under(paths.join(root, "area"), SERIES)
        )
        perf = self.view(
            "series", f"P: target to nearest tracker ({self.units})", self.L.under(paths.join(root, "P"), SERIES)
        )
        error = self.error_view([tracker], "distance of the point summary from the truth")
        states = self.view("state", "sensors: on / off", self.states())
        return _tab(f"{tracker}: I-state", site, [elements, area, perf, error, states])

    def generic(self, tracker: str) -> rrb.Container | None:
        root = paths.tracker_root(tracker)
        entities = [*self.site(), *self.truth(), *self.L.under(root, SPATIAL | FRAME)]
        site = self.map_view(f"site ({self.units})", entities)
        series = self.view("series", f"{tracker} (values)", self.L.under(root, SERIES))
        text = self.view("text", f"{tracker} log", self.L.under(root, TEXT))
        error = self.error_view([tracker], "error of each track")
        return _tab(tracker, site, [series, error, text])

    def more(self) -> rrb.Container | None:
        """Everything no family placed, by kind (in a run made by the pipeline: nothing)."""
        rest = [p for p in sorted(self.L.kinds, key=natural_key) if p not in self.placed]
        if not rest:
            return None
        k = self.L.kinds
        views = [
            self.view("map", f"map ({self.units})", [p for p in rest if k[p] & (SPATIAL | FRAME)]),
            self.view("series", "time series", [p for p in rest if k[p] & SERIES]),
            self.view("text", "log", [p for p in rest if k[p] & TEXT]),
            self.view("state", "states", [p for p in rest if k[p] & STATE]),
        ]
        left = [p for p in rest if p not in self.placed]
        if left:  # archetypes no view kind knows: a map view lists them (the viewer picks)
            views.append(View("map", "other", left))
            self.placed.update(left)
        views = [v for v in views if v is not None]
        return _named(rrb.Grid(*[v.build() for v in views]), "more") if views else None


def _built(views) -> list:
    return [v.build() if isinstance(v, View) else v for v in views if v is not None]


def _column(views, shares=None):
    items = _built(views)
    if not items:
        return None
    if len(items) == 1:
        return items[0]
    return rrb.Vertical(*items, row_shares=shares if shares and len(shares) == len(items) else None)


def _row(views, shares=None):
    items = _built(views)
    if len(items) == 1:
        return items[0]
    return rrb.Horizontal(*items, column_shares=shares if shares and len(shares) == len(items) else None)


def _named(part, name: str):
    if part is None:
        return None
    if isinstance(part, rrb.View):
        return rrb.Horizontal(part, name=name)
    part.name = name
    return part


def _tab(name: str, main: View | None, side: list[View | None]) -> rrb.Container | None:
    """A tab: the main view on the left (3/5 of the width), the others stacked on the right."""
    column = _column(side)
    parts = [p for p in (main, column) if p is not None]
    if not parts:
        return None
    return _named(_row(parts, shares=[3, 2]), name)


def tracker_roots(logged: Logged, looks: Mapping[str, Look] | None = None) -> list[str]:
    """Trackers the run logged, from their roots and their ``scores/<tracker>``, in tab order
    (their families' in :data:`~onebit.viz.families.FAMILY_ORDER`, by ``looks``)."""
    names = {r for r in logged.roots() if r not in SHARED_ROOTS}
    names |= {p.split("/")[1] for p in logged.under(paths.SCORES) if len(p.split("/")) > 1}
    order = {f: i for i, f in enumerate(FAMILY_ORDER)}
    return sorted(names, key=lambda t: (order.get(family(t, looks) or "", len(order)), natural_key(t)))


def make_blueprint(
    archetypes: Mapping[str, Iterable[str]] | Logged,
    *,
    units: str = "m",
    trail_s: float = TRAIL_S,
    ranges: Mapping[str, tuple[float, float]] | None = None,
    looks: Mapping[str, Look] | None = None,
) -> rrb.Blueprint:
    """The layout of a run from what it logged (``{entity path: archetype names}``, as
    :func:`onebit.viz.inspect.entity_archetypes` reads it): one tab per family (module
    docstring), the first of :data:`~onebit.viz.families.FAMILY_ORDER` active; ``units`` names
    the site's length unit in the titles; ``trail_s`` is the trail window in seconds; ``ranges``
    (``{entity: (min, max)}`` of the Scalars, :func:`onebit.viz.inspect.scalar_ranges`) lets the
    count plots start at 0; ``looks`` (tracker -> :class:`~onebit.viz.families.Look`, the
    pipeline's ``LOOKS``) gives each tracker its family's tab and error unit (a tracker without
    one gets the generic layout)."""
    if not (trail_s > 0):
        raise ValueError(f"trail_s must be a positive number of seconds, got {trail_s!r}")
    logged = archetypes if isinstance(archetypes, Logged) else Logged(archetypes, ranges)
    plan = Planner(logged, units=units, trail_s=trail_s, looks=looks)
    trackers = tracker_roots(logged, looks)
    residents = [t for t in trackers if family(t, looks) == "residents"]
    home = plan.home(residents)
    # a home run (no tracker but the home ones) opens on how many are in and where, the first
    # question a home user asks; a run of a paper's tracker opens on its paper's tab
    home_first = home is not None and set(trackers) <= set(residents)
    tabs = [home] if home_first else []
    intruders = [t for t in trackers if family(t, looks) == "intruder"]
    for t in trackers:
        fam = family(t, looks)
        if fam == "intruder":
            if t == intruders[0]:
                tabs.append(plan.intruder(intruders))
        elif fam is not None:
            tabs.append(getattr(plan, fam)(t))
        else:
            tabs.append(plan.generic(t))
    if not home_first and home is not None:
        tabs.append(home)
    if trackers or home is not None:
        tabs.append(plan.summary(trackers))
    if not any(tabs):  # no tracker ran: the site with the truth and the sensors
        site = plan.map_view(
            f"site ({units})", [*plan.site(), *plan.truth(), *logged.under(paths.SENSORS, SPATIAL | FRAME)]
        )
        tabs.append(
            _tab(
                "site",
                site,
                [
                    plan.view("text", "sensor log", logged.under(paths.SENSORS, TEXT)),
                    plan.view("state", "sensors: on / off", plan.states()),
                ],
            )
        )
    tabs.append(plan.more())
    tabs = [t for t in tabs if t is not None]
    root = (
        rrb.Tabs(*tabs, active_tab=0)
        if tabs
        else rrb.Tabs(rrb.TextLogView(name="nothing was logged", origin="/", contents=[]))
    )
    return rrb.Blueprint(
        root,
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed", timeline=paths.TIMELINE),
        auto_layout=False,
        auto_views=False,
    )


def save_blueprint(blueprint: rrb.Blueprint, path: str | Path, *, application_id: str = APPLICATION_ID) -> Path:
    """Write ``blueprint`` to ``path`` (an ``.rbl``) atomically, for ``application_id``."""
    path = Path(path)
    with writers.atomic_path(path, suffix=".tmp.rbl") as tmp:
        blueprint.save(application_id, tmp)
    return path


def send_run_blueprint(
    blueprint: rrb.Blueprint, path: str | Path, *, recording_id: str, application_id: str = APPLICATION_ID
) -> Path:
    """Write a recording of the run holding only ``blueprint`` (active and default) to ``path``."""
    rec = open_recording(path, recording_id=recording_id, application_id=application_id)
    try:
        rec.send_blueprint(blueprint, make_active=True, make_default=True)
    except BaseException:
        rec.disconnect()
        raise
    return close_recording(rec, path)


def save_run_blueprint(
    rrd_dir: str | Path, *, units: str = "m", trail_s: float = TRAIL_S, looks: Mapping[str, Look] | None = None
) -> Path:
    """Build the blueprint of the recordings in ``rrd_dir`` (every stage's ``*.rrd``), write it
    to ``rrd_dir/blueprint.rbl`` and send it with the run in ``rrd_dir/_blueprint.rrd`` (same
    application and recording id as the stages); returns the ``.rbl``'s path. Run again (e.g.
    with another ``trail_s``) to replace both.

    Examples
    --------
    >>> save_run_blueprint("OUT/rrd", units="ft", trail_s=30.0, looks=LOOKS)   # doctest: +SKIP
    PosixPath('OUT/rrd/blueprint.rbl')
    """
    rrd_dir = Path(rrd_dir)
    files = sorted(p for p in rrd_dir.glob("*.rrd") if p.name != BLUEPRINT_RECORDING)
    logged = Logged(entity_archetypes(files), scalar_ranges(files)) if files else Logged({})
    blueprint = make_blueprint(logged, units=units, trail_s=trail_s, looks=looks)
    out = save_blueprint(blueprint, rrd_dir / BLUEPRINT_FILE)
    ids = store_ids(files[0]) if files else []
    if ids:
        app, recording_id = ids[0]
        send_run_blueprint(blueprint, rrd_dir / BLUEPRINT_RECORDING, recording_id=recording_id, application_id=app)
    return out
