"""``onebit experiment residents DIR`` on a folder of two small written sessions (issue 22 item 5)."""

from __future__ import annotations

import numpy as np
import polars as pl

from onebit.cli import main


def _session(path, seed: int) -> None:
    """Two residents walking back and forth at opposite ends of a 6-sensor line, annotated."""
    rng = np.random.default_rng(seed)
    lines, t = [], 0.0
    pos = {1: 0, 2: 5}
    for _ in range(120):
        r = int(rng.integers(1, 3))
        pos[r] = int(
            np.clip(pos[r] + rng.choice([-1, 1]), 0, 2) if r == 1 else np.clip(pos[r] + rng.choice([-1, 1]), 3, 5)
        )
        s = f"M{pos[r] + 1:02d}"
        t += float(rng.uniform(1.0, 3.0))
        for dt, v in ((0.0, "ON"), (0.8, "OFF")):
            sec = t + dt
            lines.append(f"2008-11-10\t14:{int(sec // 60):02d}:{sec % 60:09.6f}\t{s}\t{v} {r} 1")
    lines.sort(key=lambda x: x.split("\t")[1])
    path.write_text("\n".join(lines) + "\n")


def _line_layout(tmp_path):
    """The six sensors on a line, 2 m apart, and its chain graph."""
    lay = tmp_path / "line.toml"
    lay.write_text(
        "[sensors]\n"
        + "".join(f"M{k:02d} = [{2.0 * k}, 0.0]\n" for k in range(1, 7))
        + "[graph]\nedges = ["
        + ", ".join(f'["M{k:02d}", "M{k + 1:02d}"]' for k in range(1, 6))
        + "]\n"
    )
    return lay


def test_the_study_table(tmp_path):
    sessions = tmp_path / "sessions"
    sessions.mkdir()
    _session(sessions / "P01.txt", 0)
    _session(sessions / "P02.txt", 1)
    (sessions / "README").write_text("not a session")
    res = tmp_path / "res"
    lay = _line_layout(tmp_path)  # the true line of sensors (a learned graph links what the two fire in turn)
    args = ["experiment", "residents", str(sessions), "--results", str(res), "--trackers", "hmm1"]
    assert main([*args, "--layout", str(lay)]) == 0
    df = pl.read_csv(res / "results.csv")
    assert df["session"].to_list() == ["P01"] * 3 + ["P02"] * 3 + ["mean"] * 3
    assert set(df["method"]) == {"hmm1", "baseline-busier", "baseline-nearest"}
    ok = df.filter(pl.col("session") != "mean")
    assert ok["accuracy"].is_between(0, 1).all() and (ok["events"] == 120).all()
    mean = df.filter((pl.col("session") == "mean") & (pl.col("method") == "baseline-busier"))["accuracy"][0]
    assert abs(mean - ok.filter(pl.col("method") == "baseline-busier")["accuracy"].mean()) < 1e-9
    # the nearest-previous-event baseline separates two people who never meet
    assert ok.filter(pl.col("method") == "baseline-nearest")["accuracy"].min() > 0.8  # they meet only at M03-M04
    assert (res / "runs" / "P01" / "tables" / "hmm1_events.parquet").exists()


def test_a_config_reaches_every_session_and_a_bad_one_is_refused(tmp_path):
    sessions = tmp_path / "sessions"
    sessions.mkdir()
    _session(sessions / "P01.txt", 0)
    lay = tmp_path / "line.toml"
    lay.write_text("[sensors]\n" + "".join(f"M{k:02d} = [{2.0 * k}, 0.0]\n" for k in range(1, 7)))
    cfg = tmp_path / "run.toml"
    cfg.write_text("[residents]\nhabits = true\nmeet = 3.0\n")
    res = tmp_path / "res"
    assert (
        main(
            [
                "experiment",
                "residents",
                str(sessions),
                "--results",
                str(res),
                "--trackers",
                "residents",
                "--layout",
                str(lay),
                "--targets",
                "2",
                "--config",
                str(cfg),
            ]
        )
        == 0
    )
    rec = (res / "runs" / "P01" / "run.toml").read_text()
    assert "habits = true" in rec and "meet = 3.0" in rec
    cfg.write_text("[residents]\nhabit_alpha = 0.0\n")
    assert (
        main(
            [
                "experiment",
                "residents",
                str(sessions),
                "--results",
                str(tmp_path / "bad"),
                "--trackers",
                "residents",
                "--layout",
                str(lay),
                "--config",
                str(cfg),
            ]
        )
        != 0
    )


def test_learn_a_profile_and_decode_with_known_residents(tmp_path):
    """`onebit learn residents` from labelled datasets, the profile in another dataset, `onebit run`."""
    for name, seed in (("P01", 0), ("P02", 1)):
        _session(tmp_path / f"{name}.txt", seed)
        args = ["import", "casas", str(tmp_path / f"{name}.txt"), str(tmp_path / name)]
        assert main([*args, "--layout", str(_line_layout(tmp_path)), "--targets", "2"]) == 0
    prof = tmp_path / "P02" / "residents_profile.csv"
    assert main(["learn", "residents", str(tmp_path / "P01"), "--out", str(prof)]) == 0
    assert pl.read_csv(prof)["resident"].cast(pl.String).unique().sort().to_list() == ["1", "2"]
    out = tmp_path / "run"
    assert main(["run", str(tmp_path / "P02"), "--out", str(out), "--trackers", "residents", "--no-rrd"]) == 0
    ev = pl.read_parquet(out / "tables" / "residents_events.parquet")
    assert set(ev["track"].drop_nulls()) <= {"resident1", "resident2"}
    rep = pl.read_csv(out / "report.csv")
    acc = {s: v for s, m, v in rep.select("stage", "metric", "value").iter_rows() if m == "identity_accuracy"}
    assert {"residents", "identity-habits", "identity-busier", "identity-nearest"} <= set(acc)
    assert acc["residents"] > 0.9 and acc["residents"] >= acc["identity-habits"]
    # with a clock: the habits also by the session's phase, and the run still decodes the residents
    assert (
        main(["learn", "residents", str(tmp_path / "P01"), "--out", str(prof), "--clock", "session", "--bins", "4"])
        == 0
    )
    assert set(pl.read_csv(prof)["bin"].drop_nulls()) == {f"session {k}/4" for k in range(4)}
    assert (
        main(["run", str(tmp_path / "P02"), "--out", str(tmp_path / "run2"), "--trackers", "residents", "--no-rrd"])
        == 0
    )
    ev = pl.read_parquet(tmp_path / "run2" / "tables" / "residents_events.parquet")
    assert set(ev["track"].drop_nulls()) <= {"resident1", "resident2"}
    # no labelled dataset: a clear error naming the file
    assert main(["learn", "residents", str(tmp_path / "run"), "--out", str(tmp_path / "x.csv")]) == 2


def test_cross_validation_learns_each_session_from_the_others(tmp_path):
    sessions = tmp_path / "sessions"
    sessions.mkdir()
    for name, seed in (("P01", 0), ("P02", 1), ("P03", 2)):
        _session(sessions / f"{name}.txt", seed)
    res = tmp_path / "res"
    args = ["experiment", "residents", str(sessions), "--results", str(res), "--trackers", "residents"]
    assert main([*args, "--layout", str(_line_layout(tmp_path)), "--targets", "2", "--cross-validate"]) == 0
    df = pl.read_csv(res / "results.csv")
    assert set(df["method"]) == {"residents", "baseline-busier", "baseline-nearest", "baseline-habits"}
    # each session's profile comes from the other two: its own events are not in it
    own = pl.read_csv(res / "datasets" / "P01" / "truth_events.csv").height
    prof = pl.read_csv(res / "datasets" / "P01" / "residents_profile.csv")
    assert prof.filter(pl.col("from").is_null())["count"].sum() == 240 and own == 120
    # without --cross-validate the profiles are gone: the unsupervised decoder again
    assert main([*args, "--layout", str(_line_layout(tmp_path)), "--targets", "2"]) == 0
    assert not (res / "datasets" / "P01" / "residents_profile.csv").exists()
    assert "baseline-habits" not in set(pl.read_csv(res / "results.csv")["method"])


def test_every_identity_error_is_listed(tmp_path):
    sessions = tmp_path / "sessions"
    sessions.mkdir()
    _session(sessions / "P01.txt", 0)
    res = tmp_path / "res"
    args = ["experiment", "residents", str(sessions), "--results", str(res), "--trackers", "residents"]
    assert main([*args, "--layout", str(_line_layout(tmp_path)), "--targets", "2"]) == 0
    err = pl.read_csv(res / "errors.csv")
    acc = pl.read_csv(res / "results.csv").filter((pl.col("method") == "residents") & (pl.col("session") == "P01"))
    assert err.height == round((1 - acc["accuracy"][0]) * 120)
    assert set(err["kind"]) <= {"meeting", "swap", "apart"}
