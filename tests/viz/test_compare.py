"""``onebit compare``: both runs in one recording under A/ and B/, and a blueprint that repeats
each view of the runs' own blueprints once per run (read back from the written files)."""

from __future__ import annotations

import pytest

from onebit.cli import main
from onebit.core.errors import InputError
from onebit.datasets.catalogue import get_scenario
from onebit.pipeline.runner import run_pipeline
from onebit.viz.compare import compare_runs
from onebit.viz.inspect import blueprint_views, entity_paths, query_rules, store_ids


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("cmp")
    data = get_scenario("pir14").write(
        root / "d", seed=1, duration=20.0, agents=None, drop=0.0, camera=False, params={}
    )
    a = run_pipeline(
        data, root / "seed0", trackers=("intruder",), config={"intruder": {"seed": 0, "particles": 200}}, progress=False
    )
    b = run_pipeline(
        data, root / "seed1", trackers=("intruder",), config={"intruder": {"seed": 1, "particles": 200}}, progress=False
    )
    assert a.ok and b.ok
    return root, a.out, b.out


def test_compare_puts_both_runs_on_one_recording_with_paired_views(two_runs, tmp_path):
    _, a, b = two_runs
    res = compare_runs(a, b, tmp_path / "cmp.rrd", labels=("seed 0", "seed 1"))
    assert res.chunks["A"] > 0 and res.chunks["B"] > 0
    # one recording: the viewer shows both on one timeline
    assert len(store_ids(res.rrd)) == 1
    paths = entity_paths(res.rrd)
    for side in ("A", "B"):
        assert f"{side}/intruder/tracks/intruder" in paths and f"{side}/truth/intruder" in paths
    assert not any(p.startswith(("intruder", "truth", "site")) for p in paths)  # nothing left unprefixed
    # the blueprint, read back: every view of the run's own blueprint, once per side, same kind and contents
    own = blueprint_views(a / "rrd" / "blueprint.rbl")
    got = blueprint_views(res.blueprint)
    assert res.views == len(own) and len(got) == 2 * len(own)
    for view in own:
        pair = [g for g in got if g.name.endswith(": " + view.name)]
        assert sorted(g.name.split(":")[0] for g in pair) == ["seed 0", "seed 1"]
        for g in pair:
            side = "A" if g.name.startswith("seed 0") else "B"
            assert g.kind == view.kind
            assert g.origin == f"{side}/{view.origin}".rstrip("/")
            want = [
                (inc, f"{side}/{base}".rstrip("/"), sub)
                for inc, base, sub in query_rules(view.query, origin=view.origin)
            ]
            assert query_rules(g.query, origin=g.origin) == want
            if view.kind == "2D":  # trail windows and hidden entities carried to both sides
                assert g.overrides == {f"{side}/{e}": o for e, o in view.overrides.items()}
    # the blueprint is also inside the recording
    assert blueprint_views(res.rrd)


def test_compare_cli_and_bad_input(two_runs, tmp_path, capsys):
    _, a, b = two_runs
    assert main(["compare", str(a), str(b), "--out", str(tmp_path / "c.rrd")]) == 0
    assert (tmp_path / "c.rrd").is_file() and (tmp_path / "c.rbl").is_file()
    assert "rerun " in capsys.readouterr().out
    with pytest.raises(InputError, match="not a finished run folder"):
        compare_runs(a, tmp_path / "nothing", tmp_path / "x.rrd")
    assert not (tmp_path / "x.rrd").exists()
