"""docs/extending.md, run as written: a guide whose code stops working fails here.

* **A tracker**: every ```python block that opens with a file's path (``# onebit/...py``)
  is written to that path of a scratch tree the package then imports from; the stage-list
  block's imports run and its new ``TrackerEntry`` is evaluated as written, then the pipeline
  runs the tracker on the entry's own scenario.
* **A report metric**: its module the same way, and its ``METRICS`` line evaluated beside the
  stage list's own names; every tracker that ran gets the row.
* **A sensor kind**: the ```toml block, as it is, in a ``site.toml``; a walk over the mats is
  simulated and tracked with the ``onebit`` commands the guide names.
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

import numpy as np
import polars as pl
import pytest
import shapely

import onebit.scoring
import onebit.trackers
import onebit.viz
from onebit.cli import main
from onebit.core.errors import ConfigError
from onebit.core.site import load_site
from onebit.core.tables import TRACKS
from onebit.core.writers import write_csv
from onebit.datasets.catalogue import get_scenario
from onebit.pipeline import stages as stage_list
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline
from onebit.viz.inspect import entity_paths

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "extending.md"
FENCE = re.compile(r"^```(\w+)\n(.*?)^```", re.S | re.M)
FILE = re.compile(r"# (onebit/[\w/]+\.py)\n")
STAGES = "# onebit/pipeline/stages.py:"
#: the packages a guide adds modules to (the scratch tree is put on their search path)
PACKAGES = {"trackers": onebit.trackers, "scoring": onebit.scoring, "viz": onebit.viz}


def guide(title: str) -> str:
    """The text of the guide ``# <title>``, up to the next top-level heading (outside code)."""
    lines, inside, fenced = [], False, False
    for line in DOC.read_text().splitlines(keepends=True):
        fenced ^= line.startswith("```")
        if line.startswith("# ") and not fenced:
            inside = line.strip() == f"# {title}"
        if inside:
            lines.append(line)
    assert lines, f"docs/extending.md has no '# {title}'"
    return "".join(lines)


def blocks(text: str, lang: str) -> list[str]:
    return [code for kind, code in FENCE.findall(text) if kind == lang]


def files(text: str) -> dict[str, str]:
    """The guide's ``# onebit/<path>.py`` blocks by path."""
    out = {}
    for code in blocks(text, "python"):
        m = FILE.match(code)
        if m:
            out[m.group(1)] = code
    return out


def stage_list_block(text: str) -> ast.Module:
    (code,) = [c for c in blocks(text, "python") if c.startswith(STAGES)]
    return ast.parse(code)


def follow_stage_list(text: str, name: str) -> tuple:
    """Run the stage-list block's imports, then evaluate its tuple ``name`` in the stage list's
    namespace (``...`` standing for the entries already there)."""
    tree = stage_list_block(text)
    ns = dict(vars(stage_list))
    imports = [node for node in tree.body if isinstance(node, (ast.Import, ast.ImportFrom))]
    exec(compile(ast.Module(body=imports, type_ignores=[]), str(DOC), "exec"), ns)
    (value,) = [
        node.value
        for node in tree.body
        if isinstance(node, (ast.Assign, ast.AnnAssign))
        and name in [t.id for t in (node.targets if isinstance(node, ast.Assign) else [node.target])]
    ]
    out: list = []
    for elt in value.elts:
        if isinstance(elt, ast.Constant) and elt.value is Ellipsis:
            out.extend(getattr(stage_list, name))
        else:
            out.append(eval(compile(ast.Expression(elt), str(DOC), "eval"), ns))
    return tuple(out)


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    """The modules of the tracker and metric guides, written where they say, importable."""
    root = tmp_path_factory.mktemp("guide")
    written = {**files(guide("Adding a tracker")), **files(guide("Adding a report metric"))}
    for rel, code in written.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(code)
    with pytest.MonkeyPatch.context() as mp:
        for sub, pkg in PACKAGES.items():
            mp.setattr(pkg, "__path__", [*pkg.__path__, str(root / "onebit" / sub)])
        yield written
        ours = {rel.removesuffix(".py").removesuffix("/__init__").replace("/", ".") for rel in written}
        for mod in [m for m in sys.modules if m in ours or m.rpartition(".")[0] in ours]:
            del sys.modules[mod]


@pytest.fixture(scope="module")
def entry(scratch):
    trackers = follow_stage_list(guide("Adding a tracker"), "TRACKERS")
    assert trackers[: len(stage_list.TRACKERS)] == stage_list.TRACKERS
    (new,) = trackers[len(stage_list.TRACKERS) :]
    return new


@pytest.fixture(scope="module")
def scenario_data(entry, tmp_path_factory):
    return get_scenario(entry.scenario).write(
        tmp_path_factory.mktemp("scenario") / "data",
        seed=3,
        duration=40.0,
        agents=None,
        drop=0.0,
        camera=False,
        params={},
    )


@pytest.fixture(scope="module")
def guided_run(entry, scenario_data, tmp_path_factory):
    """The guide's tracker beside a built-in one, with the metric guide's ``METRICS`` in place."""
    metrics = follow_stage_list(guide("Adding a report metric"), "METRICS")
    out = tmp_path_factory.mktemp("run") / "run"
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(stage_list, "METRICS", metrics)
        res = run_pipeline(
            scenario_data, out, trackers=("intruder", entry.name), tracker_entries=(*stage_list.TRACKERS, entry)
        )
    return res, out


def test_the_guides_name_what_their_test_writes(scratch):
    assert set(scratch) == {
        "onebit/trackers/centroid/__init__.py",
        "onebit/trackers/centroid/stage.py",
        "onebit/scoring/centroid.py",
        "onebit/viz/centroid.py",
        "onebit/scoring/rates.py",
    }


def test_the_tracker_guide_runs_as_written(entry, guided_run):
    res, out = guided_run
    assert entry.name == "centroid" and entry.gate is not None and entry.look.family == "intruder"
    assert res.status["centroid"].startswith("ok"), res.status
    tracks = pl.read_parquet(out / "tables" / "centroid_tracks.parquet")
    assert tracks.schema == TRACKS and tracks.height > 0 and tracks["tracker"].unique().to_list() == ["centroid"]
    fired = pl.read_parquet(out / "tables" / "centroid_fired.parquet")  # every returned frame is saved
    assert fired.height == tracks.height and fired["fired"].min() >= 1
    assert metric(res.report, "centroid/estimates") == tracks.height  # its scorer's rows
    assert metric(res.report, "centroid/firings_per_estimate") == pytest.approx(fired["fired"].mean())
    assert 0.0 <= metric(res.report, "centroid/hota") <= 1.0  # the MOT rows its gate turns on
    assert "centroid/tracks/person" in entity_paths(out / "rrd" / "centroid.rrd")  # its viz function


def test_the_guides_tracker_keeps_the_contract(entry, scenario_data, guided_run):
    _, out = guided_run
    site = load_site(scenario_data / "site.toml")
    motion = pl.read_parquet(out / "tables" / "motion.parquet")
    cfg = entry.spec.config()
    a, b = entry.spec.run({"motion": motion}, site, cfg), entry.spec.run({"motion": motion.clone()}, site, cfg)
    assert a["tracks"].equals(b["tracks"]) and a["fired"].equals(b["fired"])  # same inputs, same outputs
    empty = entry.spec.run({"motion": motion.clear()}, site, cfg)  # empty input: same tables, no rows
    for key in ("tracks", "fired"):
        assert empty[key].height == 0 and empty[key].schema == a[key].schema


def test_the_guides_config_section_is_read_and_checked(entry, scenario_data, tmp_path):
    entries = (*stage_list.TRACKERS, entry)
    res = run_pipeline(
        scenario_data,
        tmp_path / "a",
        trackers=("centroid",),
        tracker_entries=entries,
        config={"centroid": {"period": 4.0}},
    )
    assert res.ok, res.status
    t = pl.read_parquet(tmp_path / "a" / "tables" / "centroid_tracks.parquet")["t"].to_numpy()
    assert np.allclose((t - 2.0) % 4.0, 0.0)  # one estimate per 4 s period, at its middle
    with pytest.raises(ConfigError, match="period"):  # refused when the run starts, naming the field
        run_pipeline(
            scenario_data,
            tmp_path / "b",
            trackers=("centroid",),
            tracker_entries=entries,
            config={"centroid": {"period": 0}},
        )
    assert not (tmp_path / "b" / "run.toml").exists()


def test_the_metric_guide_reports_it_for_every_tracker_that_ran(guided_run, capsys):
    res, out = guided_run
    assert res.ok, res.status
    for tracker in ("intruder", "centroid"):
        tracks = pl.read_parquet(out / "tables" / f"{tracker}_tracks.parquet")
        minutes = (tracks["t"].max() - tracks["t"].min()) / 60.0
        assert metric(res.report, f"{tracker}/estimates_per_minute") == pytest.approx(tracks.height / minutes)
    assert main(["report", str(out)]) == 0
    assert "estimates_per_minute" in capsys.readouterr().out


def test_the_metric_guide_gives_no_row_and_nan_where_it_says(scratch):
    from onebit.scoring.rates import estimates_per_minute

    one = pl.DataFrame({"t": [5.0]})
    assert estimates_per_minute("x", {}, None, None) == []
    assert estimates_per_minute("x", {"x_tracks": one}, None, None) == []
    (row,) = estimates_per_minute("x", {"x_tracks": pl.concat([one, one])}, None, None)
    assert np.isnan(row[2])


# --------------------------------------------------------------------------- a sensor kind

MAT_SITE = """name = "mats"
units = "m"
targets = 1
[boundary]
polygon = [[0, 0], [10, 0], [10, 4], [0, 4]]
"""
#: a second mat as the guide's sensor is declared, turned by its heading
MAT2 = """[[motion_sensors]]
id = "mat2"
position = [7.0, 2.0]
heading = 90.0
type = "mat"
"""


def test_the_sensor_kind_guide_needs_site_toml_alone(tmp_path, capsys):
    (block,) = blocks(guide("Adding a sensor kind"), "toml")
    d = tmp_path / "mats"
    d.mkdir()
    (d / "site.toml").write_text(MAT_SITE + block + MAT2)
    t = np.arange(0.0, 9.01, 0.25)  # one walker along y = 2 at 1 m/s, from x = 0.5
    write_csv(pl.DataFrame({"t": t, "target": "w", "x": 0.5 + t, "y": 2.0}), d / "truth.csv")
    regions = load_site(d / "site.toml").detection_regions
    assert regions["mat1"].geometry.equals(shapely.box(2.5, 1.0, 3.5, 3.0))
    assert regions["mat2"].geometry.equals(shapely.box(6.0, 1.5, 8.0, 2.5))
    assert main(["simulate", "from-truth", str(d), "--param", "hold_s=0"]) == 0
    motion = pl.read_csv(d / "motion.csv").sort("t")
    on = {s: motion.filter((pl.col("sensor") == s) & (pl.col("value") == 1))["t"].to_list() for s in ("mat1", "mat2")}
    assert on["mat1"] == pytest.approx([2.0], abs=0.06)  # the walker steps on each mat once
    assert on["mat2"] == pytest.approx([5.5], abs=0.06)
    assert main(["run", str(d), "--out", str(tmp_path / "run"), "--trackers", "intruder", "--no-rrd"]) == 0
    capsys.readouterr()
    tracks = pl.read_parquet(tmp_path / "run" / "tables" / "intruder_tracks.parquet")
    assert tracks.height > 0 and tracks["x"].is_not_null().any()
