"""onebit.pipeline.report: a run's summary table and its skipped stages, one line per reason."""

from __future__ import annotations

import polars as pl

from onebit.cli import main
from onebit.datasets.beams_sim import write_beams_dataset
from onebit.pipeline.report import format_run_summary, load_report, skipped_groups
from onebit.pipeline.stages import stages

REPORT = pl.DataFrame(
    {
        "stage": ["beams", "beams", "beams", "beams", "istate", "rejects"],
        "metric": [
            "assignment_accuracy",
            "agent_count_error",
            "count_error",
            "unexplained_crossings",
            "containment",
            "rows",
        ],
        "value": [0.875, 0.0, 0.25, 3.0, 1.0, 0.0],
        "unit": ["fraction", "agents", "people/frame", "crossings", "fraction", "rows"],
    }
)
STATUS = {
    "crossings": "ok (0.10 s)",
    "frames": "skipped: no frames.csv in the dataset",
    "clustertrack": "skipped: input table 'proximity_frames' not produced by an earlier stage",
    "binpf": "skipped: input table 'proximity_frames' not produced by an earlier stage",
    "findinghumo": "skipped: site has no [sensor_graph] with edges",
    "hmm1": "skipped: site has no [sensor_graph] with edges",
    "beams": "ok (1.50 s)",
    "intruder": "skipped: tracker 'intruder' not selected (--trackers)",
    "residents": "skipped: tracker 'residents' not selected (--trackers)",
    "istate": "failed: boom",
    "scores/istate": "failed: cannot score",
}


def test_skipped_stages_are_one_line_per_reason_said_at_their_root():
    lines = skipped_groups(STATUS, stages())
    assert lines == [
        "skipped (no frames.csv in the dataset): frames, clustertrack, binpf",
        "skipped (site has no [sensor_graph] with edges): findinghumo, hmm1",
        "skipped (not selected (--trackers)): intruder, residents",
    ]
    # without the stage list a dependent stage keeps its own reason
    assert len(skipped_groups(STATUS)) == 4


def test_summary_has_a_row_per_stage_that_ran_with_its_paper_measures():
    text = format_run_summary(REPORT, STATUS, title="t")
    rows = {line.split("│")[1].strip(): line for line in text.splitlines() if line.startswith("│")}
    assert set(rows) == {"crossings", "beams", "istate", "rejects"}  # no skipped stage, no scores/<tracker>
    assert "1.50" in rows["beams"] and "0.25" in rows["beams"] and "assignment_accuracy 0.875" in rows["beams"]
    assert "unexplained_crossings" not in text  # the whole report is report.csv's
    assert "FAILED" in rows["istate"] and "containment 1" in rows["istate"]


def test_onebit_run_prints_the_summary_and_report_prints_every_row(tmp_path, capsys):
    data = write_beams_dataset(tmp_path / "lab", "beams-lab", seed=4, duration=30.0, agents=2, camera=False)
    assert main(["run", str(data), "--out", str(tmp_path / "run"), "--no-rrd"]) == 0
    out = capsys.readouterr().out
    report = load_report(tmp_path / "run")
    assert out.count("summary of") == 1 and "report of" not in out
    assert not any(line.endswith(": ok") for line in out.splitlines())
    skipped = [line for line in out.splitlines() if line.lstrip().startswith("skipped (")]
    assert 0 < len(skipped) < sum(1 for s in stages() if s.name not in out.split("summary of")[1])
    assert len(out.splitlines()) < 40 < report.height
    assert main(["report", str(tmp_path / "run")]) == 0
    full = capsys.readouterr().out
    assert all(f"{r['stage']}/{r['metric']}" in full for r in report.iter_rows(named=True))


def test_absent_inputs_and_what_the_site_lacks_are_one_line_each():
    status = {
        "truth_count": "skipped: no truth_count.csv in the dataset",
        "camera": "skipped: no camera.mp4 in the dataset",
        "correct": "skipped: site has no beams",
        "proximity": "skipped: site.toml has no proximity sensors",
        "ignore": "skipped: no sensor has ignore = true in site.toml",
        "intruder": "skipped: tracker 'intruder' not selected (--trackers)",
    }
    assert skipped_groups(status) == [
        "skipped (inputs not in the dataset): truth_count (truth_count.csv); camera (camera.mp4)",
        "skipped (the site lacks what they need): correct (no beams); proximity (no proximity sensors); "
        "ignore (no sensor has ignore = true)",
        "skipped (not selected (--trackers)): intruder",
    ]
