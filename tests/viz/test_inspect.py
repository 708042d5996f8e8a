"""onebit.viz.inspect: reading blueprints back and Rerun's entity-query rules."""

from __future__ import annotations

import pytest
import rerun.blueprint as rrb
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.pipeline.stages import LOOKS, TRACKERS, tracker_names
from onebit.viz import colors
from onebit.viz import inspect as rrd
from onebit.viz.blueprint import save_blueprint
from onebit.viz.colors import CAMERA_RGB
from onebit.viz.families import FAMILY_ORDER, Look


def test_query_rules_follow_rerun_docs():
    """The example of https://rerun.io/docs/reference/entity-queries."""
    q = ["+ /world/**", "- /world", "- /world/car/**", "+ /world/car/driver"]
    assert rrd.query_includes(q, "world/car/driver")
    assert not rrd.query_includes(q, "world/car/hood")
    assert not rrd.query_includes(q, "world")
    assert rrd.query_includes(q, "world/house")
    assert not rrd.query_includes(q, "elsewhere")
    assert rrd.query_includes(["$origin/**"], "a/b/c", origin="/a")
    assert not rrd.query_includes(["$origin/**"], "b", origin="/a")


def test_blueprint_read_back(tmp_path):
    bp = rrb.Blueprint(
        rrb.Tabs(
            rrb.Horizontal(
                rrb.Spatial2DView(
                    name="map (m)",
                    origin="/",
                    contents=["+ truth/a", "+ truth/a/trail", "+ truth/a/path"],
                    overrides={
                        "truth/a/path": [rrb.EntityBehavior(visible=False)],
                        "truth/a/trail": [
                            rrb.VisibleTimeRanges(
                                [
                                    rrb.VisibleTimeRange(
                                        "t",
                                        start=rrb.TimeRangeBoundary.cursor_relative(seconds=-10.0),
                                        end=rrb.TimeRangeBoundary.cursor_relative(seconds=0.0),
                                    )
                                ]
                            )
                        ],
                    },
                ),
                name="first",
            ),
            rrb.TimeSeriesView(name="error (m)", origin="/", contents=["+ scores/x/a"]),
        ),
    )
    path = save_blueprint(bp, tmp_path / "b.rbl")
    views = {v.name: v for v in rrd.blueprint_views(path)}
    assert views["map (m)"].kind == "2D" and views["error (m)"].kind == "TimeSeries"
    assert views["map (m)"].overrides == {
        "truth/a/path": {"visible": False},
        "truth/a/trail": {"time_range": (-10.0, 0.0)},
    }
    assert rrd.blueprint_tabs(path) == ["first", "error (m)"]


def test_every_tracker_has_a_family_and_a_colour_apart_from_truth():
    """Each tracker's look is declared on its entry (one place): a family with a tab, a colour
    of its own, apart from the truth's; its error unit is its MOT gate's."""
    assert set(LOOKS) == set(tracker_names())
    assert all(look.family in FAMILY_ORDER and look.rgb is not None for look in LOOKS.values())
    rgbs = [look.rgb for look in LOOKS.values()]
    assert len(set(rgbs)) == len(rgbs) and CAMERA_RGB not in rgbs
    truth = colors.TRUTH[:3]
    shades = [colors.track_color(t, k, 3, rgb=look.rgb)[:3] for t, look in LOOKS.items() for k in range(3)]
    assert truth not in shades
    assert len({colors.track_color("findinghumo", k, 3, rgb=LOOKS["findinghumo"].rgb) for k in range(3)}) == 3
    for e in TRACKERS:
        assert e.drawn.hops == (e.gate is not None and e.gate.unit == "hops"), e.name
    assert {t for t, look in LOOKS.items() if look.hops} == {"beams", "findinghumo", "hmm1", "hmm2", "findinghumo-flow"}


def test_a_look_names_a_known_family_and_a_colour():
    with pytest.raises(ValueError, match="Look.family = 'nope'"):
        Look("nope")
    with pytest.raises(ValueError, match="Look.rgb"):
        Look("beams", (1, 2, 300))
    assert colors.tracker_color("new-tracker") == colors.color_of("new-tracker")  # no look: a palette colour


_VALUE = st.one_of(st.none(), st.just(float("nan")), st.floats(-1e6, 1e6))


@settings(max_examples=80, deadline=None)
@given(
    st.lists(st.one_of(st.none(), st.lists(_VALUE, max_size=4)), max_size=8),
    st.integers(0, 3),
    st.booleans(),
)
def test_list_min_max_equals_pyarrow_compute(rows, cut, large):
    """The blueprint's Scalars ranges from the Arrow buffers equal pyarrow.compute's min_max of
    the flattened lists: nulls skipped, NaN ignored unless all are NaN, None without a value;
    sliced arrays and large lists too."""
    import math

    import pyarrow as pa
    import pyarrow.compute as pc

    from onebit.viz.inspect import list_min_max

    typ = pa.large_list(pa.float64()) if large else pa.list_(pa.float64())
    col = pa.array(rows, typ).slice(min(cut, len(rows)))
    mm = pc.min_max(pc.list_flatten(col))
    want = (mm["min"].as_py(), mm["max"].as_py())
    got = list_min_max(col)
    for w, g in zip(want, got):
        assert (w is None and g is None) or (
            w is not None and g is not None and (w == g or (math.isnan(w) and math.isnan(g)))
        )
