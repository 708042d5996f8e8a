"""Two runs side by side on one timeline: ``onebit compare RUN_A RUN_B``.

The stage recordings of one run share one recording id, so ``rerun RUN/rrd/*.rrd`` opens a
run as one recording. Two runs are two recordings, and a Rerun view shows one recording at a
time; they also use the same entity paths (``intruder/tracks/intruder`` in both), so merging
their files into one recording would draw one over the other. :func:`compare_runs` therefore
copies every chunk of both runs' recordings into **one** new recording under a prefix per run
(``A/...`` and ``B/...``, :meth:`rerun.chunk.Chunk.with_entity_path`, no re-logging: the data
is the runs' own), and writes a blueprint that repeats each view of the runs' own blueprints
(``RUN/rrd/blueprint.rbl``: the 2-D site view, the sensor state timeline, the error plot, ...)
once per run, side by side, on the shared timeline ``t``::

    rerun compare.rrd compare.rbl

The spatial views keep their per-entity overrides (trail windows, hidden coverage maps) on
both sides; other view properties (backgrounds, axis ranges) take Rerun's defaults.
"""

from __future__ import annotations

import uuid
from dataclasses import dataclass
from pathlib import Path

from onebit.core.errors import InputError
from onebit.core.lazy import lazy_module
from onebit.viz import paths
from onebit.viz.blueprint import save_blueprint
from onebit.viz.inspect import ViewInfo, blueprint_views, query_rules
from onebit.viz.recording import close_recording, discard_recording, open_recording, rerun_enabled

rr = lazy_module("rerun")
rrb = lazy_module("rerun.blueprint")

#: Rerun's view class identifier -> the blueprint class that makes it.
_VIEW_CLASSES = {
    "2D": "Spatial2DView",
    "3D": "Spatial3DView",
    "TimeSeries": "TimeSeriesView",
    "StateTimeline": "StateTimelineView",
    "TextLog": "TextLogView",
    "BarChart": "BarChartView",
}


@dataclass(frozen=True)
class Comparison:
    """What :func:`compare_runs` wrote."""

    rrd: Path
    blueprint: Path
    chunks: dict[str, int]  # prefix -> chunks copied
    views: int  # views per side


def _run_files(run: Path) -> list[Path]:
    rrd = run / "rrd"
    files = sorted(p for p in rrd.glob("*.rrd") if not p.name.startswith("_")) if rrd.is_dir() else []
    if not files:
        raise InputError("no Rerun recordings (rrd/*.rrd): not a finished run folder", file=run)
    return files


def _prefixed(path: str, prefix: str) -> str:
    path = path.strip("/")
    return f"/{prefix}/{path}" if path else f"/{prefix}"


def _query(view: ViewInfo, prefix: str) -> list[str]:
    out = []
    for include, base, subtree in query_rules(view.query, origin=view.origin):
        target = _prefixed(base, prefix) + ("/**" if subtree else "")
        out.append(("+ " if include else "- ") + target)
    return out


def _overrides(view: ViewInfo, prefix: str) -> dict[str, list] | None:
    """The view's per-entity visibility and trail windows (cursor-relative time ranges on ``t``)."""
    out: dict[str, list] = {}
    for entity, o in view.overrides.items():
        target = _prefixed(entity, prefix)
        if "visible" in o:
            out.setdefault(target, []).append(rrb.EntityBehavior(visible=o["visible"]))
        if "time_range" in o:
            start, end = o["time_range"]
            out.setdefault(target, []).append(
                rrb.VisibleTimeRanges(
                    [
                        rrb.VisibleTimeRange(
                            paths.TIMELINE,
                            start=rrb.TimeRangeBoundary.cursor_relative(seconds=float(start)),
                            end=rrb.TimeRangeBoundary.cursor_relative(seconds=float(end)),
                        )
                    ]
                )
            )
    return out or None


def _view(view: ViewInfo, prefix: str, label: str):
    cls = getattr(rrb, _VIEW_CLASSES[view.kind])
    kw = {"overrides": _overrides(view, prefix)} if view.kind in ("2D", "3D") else {}
    return cls(name=f"{label}: {view.name}", origin=_prefixed(view.origin, prefix), contents=_query(view, prefix), **kw)


def compare_blueprint(
    views_a: list[ViewInfo], views_b: list[ViewInfo], *, labels: tuple[str, str], prefixes: tuple[str, str] = ("A", "B")
):
    """One row per view (A's views first, then B's that A lacks; a view is its name, kind, origin
    and contents: two tabs may each hold a view of one name, say the sensors' on/off bands): the
    view for run A and the same view for run B side by side. Views of a kind without a blueprint
    class are left out."""
    by_name: dict[tuple, list[ViewInfo]] = {}
    for v in [*views_a, *views_b]:
        key = (v.name, v.kind, v.origin, tuple(v.query))
        if v.kind in _VIEW_CLASSES and key not in by_name:
            by_name[key] = [v]
    rows = [
        rrb.Horizontal(_view(v, prefixes[0], labels[0]), _view(v, prefixes[1], labels[1]), name=v.name)
        for (v,) in by_name.values()
    ]
    if not rows:
        raise InputError("the runs' blueprints hold no view to repeat")
    return rrb.Blueprint(rrb.Vertical(*rows), collapse_panels=False), len(rows)


def compare_runs(
    run_a: str | Path, run_b: str | Path, out: str | Path, *, labels: tuple[str, str] | None = None
) -> Comparison:
    """Write ``out`` (``.rrd``: both runs' data under ``A/`` and ``B/`` in one recording, with
    the blueprint sent in) and ``out`` with suffix ``.rbl`` (the blueprint alone), atomically.

    ``labels`` name the sides in the view titles (default: the run folders' names).
    """
    run_a, run_b, out = Path(run_a), Path(run_b), Path(out)
    labels = labels or (run_a.name, run_b.name)
    files = {"A": _run_files(run_a), "B": _run_files(run_b)}
    bps = []
    for run in (run_a, run_b):
        bp = run / "rrd" / "blueprint.rbl"
        bps.append(blueprint_views(bp) if bp.is_file() else [])
    blueprint, n_views = compare_blueprint(bps[0], bps[1], labels=labels)
    from rerun.chunk import RrdReader

    chunks = {"A": 0, "B": 0}
    with rerun_enabled():
        rec = open_recording(out, recording_id=str(uuid.uuid4()))
        try:
            for prefix, paths in files.items():
                for f in paths:
                    reader = RrdReader(str(f))
                    for store in reader.recordings():
                        moved = [
                            c.with_entity_path(_prefixed(c.entity_path, prefix))
                            for c in reader.stream(store=store)
                            if not c.entity_path.strip("/").startswith("__")  # Rerun's own properties
                        ]
                        rr.send_chunks(moved, recording=rec)
                        chunks[prefix] += len(moved)
            rec.send_blueprint(blueprint)
        except BaseException:
            discard_recording(rec, out)
            raise
        close_recording(rec, out)
        rbl = save_blueprint(blueprint, out.with_suffix(".rbl"))
    return Comparison(out, rbl, chunks, n_views)
