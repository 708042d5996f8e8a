"""``onebit simulate from-truth`` (issue 12, item 5): the logs a site would record of given walks."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import polars as pl
import pytest

from onebit.cli import main
from onebit.core.errors import ConfigError, InputError
from onebit.core.sensing import detection_regions
from onebit.core.site import load_site
from onebit.datasets.catalogue import get_scenario
from onebit.datasets.from_truth import FromTruthConfig, simulate_from_truth
from onebit.datasets.irtracking import import_irtracking
from onebit.datasets.irtracking_sim import write_irtracking
from onebit.pipeline.report import metric
from onebit.pipeline.runner import run_pipeline
from onebit.readers.motion import read_motion_csv


def _walks_of(scenario: str, root: Path, duration: float | None = 40.0) -> Path:
    """A folder holding only a scenario's site.toml and truth.csv (as if imported)."""
    src = get_scenario(scenario).write(
        root / f"{scenario}-src", seed=4, duration=duration, agents=None, drop=0.0, camera=False, params={}
    )
    dst = root / scenario
    dst.mkdir()
    for name in ("site.toml", "truth.csv"):
        shutil.copy(src / name, dst / name)
    return dst


def test_beams_from_truth_decode_to_the_true_crossings(tmp_path):
    d = _walks_of("beams-building", tmp_path, 90.0)
    assert main(["simulate", "from-truth", str(d), "--seed", "2"]) == 0
    res = run_pipeline(d, tmp_path / "run", trackers=("beams", "istate"), rrd=False)
    assert metric(res.report, "crossings/decoded_match") == 1.0  # body width: a crossing when the body clears
    assert metric(res.report, "beams/agent_count_error") == 0.0
    assert metric(res.report, "istate/containment") == 1.0


def test_pir_fov_hold_and_refractory(tmp_path):
    d = _walks_of("istate-room", tmp_path, 60.0)
    site_text = (d / "site.toml").read_text().replace("fov = [[0.5", "refractory = 3.0\nfov = [[0.5", 1)
    (d / "site.toml").write_text(site_text)
    site = load_site(d / "site.toml")
    refractory = {m.id: m.refractory for m in site.motion_sensors}
    assert max(refractory.values()) == 3.0
    counts = simulate_from_truth(d, seed=1, cfg=FromTruthConfig(hold_s=0.5))
    assert counts["targets"] == 2 and counts["motion_edges"] > 0
    edges = read_motion_csv(d / "motion.csv", list(refractory)).motion.sort("t")
    for sid, f in refractory.items():  # after an off edge the sensor is blind for its refractory period
        e = edges.filter(pl.col("sensor") == sid)
        off_then_on = e.with_columns(gap=pl.col("t") - pl.col("t").shift(1)).filter(
            pl.col("on") & pl.col("gap").is_not_null()
        )
        assert (off_then_on["gap"] >= f - 1e-6).all(), sid
    # on only while someone is in the fov (or within the hold after)
    truth = pl.read_csv(d / "truth.csv")
    reg = detection_regions(site)["m1"]
    inside = truth.filter(pl.Series(reg.covers_xy(truth["x"].to_numpy(), truth["y"].to_numpy())))
    on_times = edges.filter((pl.col("sensor") == "m1") & pl.col("on"))["t"].to_numpy()
    if len(on_times):
        assert np.min(np.abs(on_times[:, None] - inside["t"].to_numpy()[None, :]), axis=1).max() <= 0.1
    res = run_pipeline(d, tmp_path / "run", trackers=("istate",), rrd=False)
    assert metric(res.report, "istate/containment") == 1.0  # run.toml [istate] got the hold and the top speed


def test_proximity_from_truth(tmp_path):
    d = _walks_of("proximity-grid", tmp_path, None)
    simulate_from_truth(d, seed=0)
    prox = pl.read_csv(d / "proximity.csv")
    assert set(prox["value"].unique()) == {0, 1}
    res = run_pipeline(d, tmp_path / "run", trackers=("istate",), rrd=False)
    assert res.status["istate"].startswith("ok") and metric(res.report, "istate/containment") == 1.0


def test_deployment_planning_from_an_export(tmp_path):
    """Real-looking walks -> truth.csv -> a site with a beam to try -> its log -> the report."""
    export = tmp_path / "walks.csv"
    t = np.arange(0.0, 20.0, 0.2)
    export.write_text("t,id,x,y\n" + "".join(f"{a:.1f},p1,{1 + 0.4 * a:.3f},2.0\n" for a in t))
    d = tmp_path / "plan"
    assert main(["import", "trajectories", str(export), str(d)]) == 0
    site = (d / "site.toml").read_text()
    site += '\n[[beams]]\nid = "door"\nsegment = [[5.0, 1.0], [5.0, 3.0]]\nforward = "right"\nspacing = 0.05\n'
    (d / "site.toml").write_text(site)
    assert main(["simulate", "from-truth", str(d)]) == 0
    res = run_pipeline(d, tmp_path / "run", trackers=("beams",), rrd=False)
    assert metric(res.report, "crossings/decoded") == 1.0 and metric(res.report, "crossings/decoded_match") == 1.0


def test_bad_folders_and_options(tmp_path):
    with pytest.raises(InputError, match="site.toml"):
        simulate_from_truth(tmp_path)
    (tmp_path / "site.toml").write_text("[boundary]\npolygon = [[0, 0], [1, 0], [1, 1]]\n")
    with pytest.raises(InputError, match="no sensor"):
        simulate_from_truth(tmp_path)
    with pytest.raises(ConfigError, match="p_detect"):
        FromTruthConfig(p_detect=0.0)
    assert main(["simulate", "from-truth", str(tmp_path), "--param", "speed=3"]) == 2


def test_binary_sensors_from_truth_write_a_frame_log(tmp_path):
    """[[binary_sensors]]: frames.csv at frame_hz, a sensor active when someone is within R_i
    (p_detect 1), the same sets the truth gives at those times; a mixed site is refused."""
    files = write_irtracking(tmp_path / "data", frames=24, people=2, seed=5)
    d = tmp_path / "ds"
    import_irtracking(files.readings, d, truth=files.truth, radius=0.8, targets=2)
    (d / "frames.csv").unlink()
    assert main(["simulate", "from-truth", str(d), "--seed", "1", "--param", "frame_hz=2"]) == 0
    assert not (d / "motion.csv").exists() and not (d / "proximity.csv").exists()
    site = load_site(d / "site.toml")
    frames = pl.read_csv(d / "frames.csv", schema_overrides={"active": pl.String})
    truth = pl.read_csv(d / "truth.csv", schema_overrides={"target": pl.String})
    pos = {b.id: b.position for b in site.binary_sensors}
    assert np.allclose(np.diff(frames["t"].to_numpy()), 0.5)
    for t, active in frames.iter_rows():
        here = truth.filter(pl.col("t").is_between(t - 1e-6, t + 1e-6))
        want = {
            s
            for s, (x, y) in pos.items()
            if any(np.hypot(x - a, y - b) <= 0.8 for a, b in here.select("x", "y").rows())
        }
        assert set((active or "").split()) == want, t
    res = run_pipeline(d, tmp_path / "run", trackers=("istate",), rrd=False)
    assert res.status["frames"].startswith("ok") and metric(res.report, "frames/frames") == frames.height
    text = (d / "site.toml").read_text() + '\n[[motion_sensors]]\nid = "pir"\nposition = [1.0, 1.0]\nrange = 2.0\n'
    (d / "site.toml").write_text(text)
    with pytest.raises(InputError, match="mixes"):
        simulate_from_truth(d)
