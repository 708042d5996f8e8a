"""site.toml validation and the region decomposition."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from onebit.core.errors import SiteError
from onebit.core.region_graph import build_region_graph
from onebit.core.site import load_site, site_from_dict
from onebit.datasets.builtin import builtin_site_path

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
        (
            lambda t: t.replace("[[0, 0], [10, 0], [10, 4], [0, 4]]", "[[0, 0], [10, 4], [10, 0], [0, 4]]"),
            "boundary.polygon",
        ),
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


# --------------------------------------------------------------------------- units and sensors (one sensor model)


@pytest.mark.parametrize("units", ['"parsec"', "3", '["m"]', '"M"'])
def test_units_must_be_a_known_unit(tmp_path, units):
    with pytest.raises(SiteError) as exc:
        _load(tmp_path, BASE.replace('units = "m"', f"units = {units}"))
    assert "field 'units'" in str(exc.value)


@pytest.mark.parametrize("units", ["m", "cm", "mm", "ft", "in"])
def test_every_unit_of_the_unit_table_loads(tmp_path, units):
    assert _load(tmp_path, BASE.replace('units = "m"', f'units = "{units}"')).units == units


def test_units_default_to_metres(tmp_path):
    assert _load(tmp_path, BASE.replace('units = "m"\n', "")).units == "m"


def test_motion_sensor_type_is_none_unless_declared(tmp_path):
    text = (
        BASE
        + '[[motion_sensors]]\nid = "m"\nposition = [1, 1]\nrange = 1.5\n[[motion_sensors]]\nid = "n"\nposition = [8, 2]\ntype = "pir"\n'
    )
    site = _load(tmp_path, text)
    assert [m.type for m in site.motion_sensors] == [None, "pir"]
    regions = site.detection_regions
    assert list(regions) == ["m", "n", "a"]
    assert regions["m"].radius == 1.5 and regions["n"].extent is not None and regions["a"].kind == "beam"


def test_a_sensor_without_a_region_loads_and_fails_when_its_region_is_needed(tmp_path):
    site = _load(tmp_path, BASE + '[[motion_sensors]]\nid = "m"\nposition = [1, 1]\n')
    with pytest.raises(SiteError) as exc:
        _ = site.detection_regions
    assert "field 'motion_sensors[0] (id 'm')'" in str(exc.value) and "site.toml" in str(exc.value)


@settings(max_examples=30, deadline=None)
@given(
    sensors=st.lists(
        st.tuples(st.floats(0.5, 9.5), st.floats(0.5, 3.5), st.one_of(st.none(), st.floats(0.1, 5.0)), st.booleans()),
        min_size=1,
        max_size=6,
    )
)
def test_loaded_motion_sensors_have_the_regions_they_declare(sensors):
    ms = []
    for i, (x, y, rng, with_fov) in enumerate(sensors):
        m = {"id": f"s{i}", "position": [x, y]}
        if rng is not None:
            m["range"] = rng
        if with_fov or rng is None:
            m["fov"] = [[x - 0.5, y - 0.5], [x + 0.5, y - 0.5], [x + 0.5, y + 0.5], [x - 0.5, y + 0.5]]
        ms.append(m)
    site = site_from_dict(
        {"units": "cm", "boundary": {"polygon": [[0, 0], [10, 0], [10, 4], [0, 4]]}, "motion_sensors": ms}
    )
    regions = site.detection_regions
    for m in ms:
        r = regions[m["id"]]
        assert r.radius == m.get("range") and (r.fov is not None) == ("fov" in m)
        assert r.covers_xy([m["position"][0]], [m["position"][1]]).all()  # every region holds its sensor here


# --------------------------------------------------------------------------- every value checked at load

CAMERA = """
[camera]
width = 640
height = 480
fps = 10.0
homography = [[0.01, 0, 0], [0, 0.01, 0], [0, 0, 1]]
"""


@pytest.mark.parametrize(
    "text, key",
    [
        (BASE.replace("spacing = 0.1", "spacing = nan"), "beams[0] (id 'a').spacing"),
        (BASE.replace("spacing = 0.1", "spacing = inf"), "beams[0] (id 'a').spacing"),
        (BASE.replace("spacing = 0.1", 'spacing = "0.1"'), "beams[0] (id 'a').spacing"),
        (BASE.replace('id = "a"', "id = true"), "beams[0].id"),
        (BASE.replace('id = "a"', "id = 1.5"), "beams[0].id"),
        (BASE.replace('name = "t"', "name = [1, 2]"), "name"),
        (BASE + CAMERA.replace("width = 640", "width = true"), "camera.width"),
        (BASE + CAMERA.replace("width = 640", "width = 640.0"), "camera.width"),
        (BASE + CAMERA.replace("fps = 10.0", "fps = nan"), "camera.fps"),
        (BASE + CAMERA.replace("fps = 10.0", "fps = -inf"), "camera.fps"),
        (BASE + CAMERA + "t0 = nan\n", "camera.t0"),
        ('epoch = "yesterday"\n' + BASE, "epoch"),
        ("epoch = 12:00:00\n" + BASE, "epoch"),
        (BASE + '[[regions]]\nname = "r"\npoint = [1, 1]\ncapacity = true\n', "regions[0].capacity"),
        (BASE + '[[regions]]\nname = ""\npoint = [1, 1]\n', "regions[0].name"),
        (BASE.replace('forward = "right"', 'forward = "right"\ncapacity = -1'), "beams[0] (id 'a').capacity"),
    ],
)
def test_bad_values_are_refused_at_load_naming_the_key(tmp_path, text, key):
    with pytest.raises(SiteError) as info:
        _load(tmp_path, text)
    assert f"field '{key}'" in str(info.value)


def test_good_epoch_and_camera_load(tmp_path):
    site = _load(tmp_path, 'epoch = "2024-05-01T08:00:00Z"\n' + BASE + CAMERA)
    assert site.epoch == "2024-05-01T08:00:00Z" and site.camera.fps == 10.0
    assert _load(tmp_path, "epoch = 2024-05-01T08:00:00Z\n" + BASE).epoch.startswith("2024-05-01T08:00:00")


def test_not_utf8_and_deep_nesting_are_site_errors(tmp_path):
    p = tmp_path / "site.toml"
    p.write_bytes(BASE.encode().replace(b'name = "t"', b'name = "t\xff"'))
    with pytest.raises(SiteError, match=r"site\.toml:2: not UTF-8 text: byte 0xFF at column 10"):
        load_site(p)
    p.write_text("x = " + "[" * 20000 + "]" * 20000 + "\n" + BASE)
    with pytest.raises(SiteError, match="nested too deeply"):
        load_site(p)
    p.write_text(BASE.replace('name = "t"', 'name = "' + "n" * 100_000 + '"\nbogus = 1'))
    with pytest.raises(SiteError) as info:
        load_site(p)
    assert len(str(info.value)) < 3000


@st.composite
def _mutated_site(draw) -> bytes:
    data = bytearray((BASE + CAMERA).encode())
    for _ in range(draw(st.integers(1, 4))):
        pos = draw(st.integers(0, len(data)))
        op = draw(st.sampled_from(["flip", "insert", "delete", "nest", "huge"]))
        if op == "flip" and data:
            data[min(pos, len(data) - 1)] ^= 1 << draw(st.integers(0, 7))
        elif op == "insert":
            data[pos:pos] = draw(
                st.sampled_from([b'"', b"[", b"]", b"\n", b"=", b"\xff", b"nan", b"inf", b"true", b"{", b"#"])
            )
        elif op == "delete":
            del data[pos : pos + draw(st.integers(1, 6))]
        elif op == "nest":
            k = draw(st.sampled_from([3, 500, 5000]))
            data[pos:pos] = b"x = " + b"[" * k + b"]" * k + b"\n"
        else:
            data[pos:pos] = b"y" * 50_000
    return bytes(data)


@settings(max_examples=120, deadline=None)
@given(blob=st.one_of(st.binary(max_size=300), _mutated_site()))
def test_site_fuzz_only_site_errors_and_bounded(tmp_path_factory, blob):
    p = tmp_path_factory.mktemp("site") / "site.toml"
    p.write_bytes(blob)
    try:
        load_site(p)
    except SiteError as exc:
        assert len(str(exc)) <= 2300


@pytest.mark.parametrize(
    "h", ["[[0.0],[0,0.0],[]]", "[[1,0,0],[0,1,0],[0,0,true]]", "[]", '[[1,0,0],[0,1,0],[0,0,"1"]]']
)
def test_ragged_or_mistyped_homography_is_a_site_error(tmp_path, h):
    # found by the site fuzz test: a ragged matrix reached numpy and raised a ValueError
    p = tmp_path / "site.toml"
    p.write_text(
        'name="t"\nunits="m"\n[boundary]\npolygon=[[0,0],[10,0],[10,4],[0,4]]\n'
        f"[camera]\nwidth=6\nheight=4\nfps=10\nhomography={h}\n"
    )
    with pytest.raises(SiteError, match=r"camera\.homography"):
        load_site(p)


# --------------------------------------------------------------------------- ignore = true


def _ignore_site(flags: list[bool | None], typed: list[bool], type_ignore: bool) -> dict:
    """A site of 4 binary sensors in a row with a connected geometric graph: sensor i says
    ``ignore = flags[i]`` (``None``: says nothing) and is of type ``hot`` when ``typed[i]``."""
    sensors = []
    for i, (flag, typ) in enumerate(zip(flags, typed)):
        s = {"id": f"s{i}", "position": [1.0 + 2 * i, 2.0], "radius": 1.0}
        if flag is not None:
            s["ignore"] = flag
        if typ:
            s["type"] = "hot"
        sensors.append(s)
    return {
        "boundary": {"polygon": [[0, 0], [10, 0], [10, 4], [0, 4]]},
        "binary_sensors": sensors,
        "sensor_types": {"hot": {"ignore": type_ignore}},
        "sensor_graph": {"geometry": "connected"},
    }


@settings(max_examples=40, deadline=None)
@given(
    flags=st.lists(st.sampled_from([None, True, False]), min_size=4, max_size=4),
    typed=st.lists(st.booleans(), min_size=4, max_size=4),
    type_ignore=st.booleans(),
)
def test_ignored_sensors_are_known_to_readers_and_left_out_for_trackers(flags, typed, type_ignore):
    site = site_from_dict(_ignore_site(flags, typed, type_ignore))
    expect = {f"s{i}" for i, (f, t) in enumerate(zip(flags, typed)) if f is True or (f is None and t and type_ignore)}
    assert site.ignored == expect
    every = {f"s{i}" for i in range(4)}
    # the readers' view: every sensor, ignored or not
    assert {m.id for m in site.motion_sensors} == every
    assert {p.id for p in site.proximity_sensors} == every
    assert set(site.signals) == every
    # the trackers' view: none of the ignored
    tracked = site.tracked
    assert {m.id for m in tracked.motion_sensors} == every - expect
    assert {p.id for p in tracked.proximity_sensors} == every - expect
    assert {b.id for b in tracked.binary_sensors} == every - expect
    assert set(site.sensor_graph.nodes) == every - expect
    assert all(expect.isdisjoint(e) for e in site.sensor_graph.edges)
    assert (tracked is site) == (not expect)


def test_explicit_graph_edges_at_an_ignored_sensor_are_dropped():
    data = _ignore_site([None, True, None, None], [False] * 4, False)
    data["sensor_graph"] = {"edges": [["s0", "s1"], ["s1", "s2"], ["s2", "s3"]], "entries": ["s1", "s0"]}
    site = site_from_dict(data)
    assert site.sensor_graph.edges == (("s2", "s3"),)
    assert site.sensor_graph.entries == ("s0",)


@pytest.mark.parametrize(
    "edit, key",
    [
        (lambda d: d["binary_sensors"][0].update(ignore="yes"), "binary_sensors[0] (id 's0').ignore"),
        (lambda d: d["sensor_types"]["hot"].update(ignore=1), "sensor_types.hot.ignore"),
    ],
)
def test_ignore_must_be_a_boolean(edit, key):
    data = _ignore_site([None] * 4, [True] * 4, False)
    edit(data)
    with pytest.raises(SiteError) as exc:
        site_from_dict(data)
    assert key in str(exc.value)


def test_an_ignored_beam_keeps_its_regions(tmp_path):
    site = _load(tmp_path, BASE.replace("spacing = 0.1", "spacing = 0.1\nignore = true"))
    assert site.ignored == {"a"}
    assert site.tracked.beam_ids == ("a",)
    assert build_region_graph(site).names == ("r1", "r2")
