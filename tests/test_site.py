"""site.toml validation and the region decomposition."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.datasets.region_graph import build_region_graph
from onebit.datasets.site import builtin_site_path, load_site, site_from_dict
from onebit.errors import SiteError

BASE = """
name = "t"
units = "m"
[boundary]
polygon = [[0, 0], [10, 0], [10, 4], [0, 4]]
[[beams]]
id = "a"
segment = [[5, 0], [5, 4]]
forward = "right"
spacing = 0.1
"""


def _load(tmp_path, text):
    p = tmp_path / "site.toml"
    p.write_text(text)
    return load_site(p)


def test_minimal_site_two_regions(tmp_path):
    site = _load(tmp_path, BASE)
    rg = build_region_graph(site)
    assert rg.names == ("r1", "r2")
    # segment (5,0)->(5,4) points up; its right side is +x, so forward goes r1 (left) -> r2
    assert rg.endpoints("a", 1) == ("r1", "r2")


@pytest.mark.parametrize(
    "edit, key",
    [
        (lambda t: t.replace('units = "m"', 'units = "parsec"'), "units"),
        (lambda t: t.replace("segment = [[5, 0], [5, 4]]", "segment = [[5, 1], [5, 4]]"), "segment"),
        (lambda t: t.replace("[[0, 0], [10, 0], [10, 4], [0, 4]]", "[[0, 0], [10, 4], [10, 0], [0, 4]]"), "boundary.polygon"),
        (lambda t: t + "colour = 3\n", "colour"),
        (lambda t: t.replace('id = "a"\n', ""), "id"),
        (lambda t: t.replace('forward = "right"', 'forward = "up"'), "forward"),
        (lambda t: t.replace("[boundary]\npolygon = [[0, 0], [10, 0], [10, 4], [0, 4]]", ""), "boundary"),
        (lambda t: t + "[camera]\nwidth = 10\nheight = 10\n", "camera.homography"),
        (lambda t: t.replace("units", "units = = "), "TOML"),
    ],
)
def test_broken_site_names_the_key(tmp_path, edit, key):
    with pytest.raises(SiteError) as exc:
        _load(tmp_path, edit(BASE))
    msg = str(exc.value)
    assert "site.toml" in msg and key in msg


def test_crossing_beams_are_refused():
    data = {
        "boundary": {"polygon": [[0, 0], [10, 0], [10, 10], [0, 10]]},
        "beams": [
            {"id": "a", "segment": [[5, 0], [5, 10]]},
            {"id": "b", "segment": [[0, 5], [10, 5]]},
        ],
    }
    with pytest.raises(SiteError, match="crosses beam 'a'"):
        site_from_dict(data)


def test_builtin_sites_load():
    for name in ("building", "lab"):
        site = load_site(builtin_site_path(name))
        assert site.camera is not None


@settings(max_examples=40, deadline=None)
@given(
    w=st.floats(2, 50),
    h=st.floats(2, 50),
    cuts=st.lists(st.floats(0.05, 0.95), min_size=1, max_size=5, unique=True),
)
def test_k_parallel_beams_make_k_plus_1_regions_in_a_chain(w, h, cuts):
    """k disjoint wall-to-wall beams across a rectangle split it into a chain of k+1 regions."""
    cuts = sorted(cuts)
    if min((b - a for a, b in zip(cuts, cuts[1:])), default=1.0) * w < 1e-3:
        return
    data = {
        "boundary": {"polygon": [[0, 0], [w, 0], [w, h], [0, h]]},
        "beams": [{"id": f"b{i}", "segment": [[c * w, 0], [c * w, h]], "forward": "right"} for i, c in enumerate(cuts)],
    }
    rg = build_region_graph(site_from_dict(data))
    assert len(rg.names) == len(cuts) + 1
    assert rg.graph.number_of_edges() == 2 * len(cuts)
    assert abs(sum(p.area for p in rg.polygons) - w * h) < 1e-4 * w * h  # minus the thin slits cut along the beams
    # forward crossings go left to right along the chain
    order = [rg.beam_source[f"b{i}"] for i in range(len(cuts))] + [rg.beam_target[f"b{len(cuts) - 1}"]]
    assert len(set(order)) == len(cuts) + 1
