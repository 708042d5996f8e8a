"""Progress that tells the truth: the running stage is named before it runs, long stages move
the bar from inside (intruder iterations, HMM windows) through the callback trackers get in
their inputs, and nothing is drawn when not on a terminal or in CI."""

from __future__ import annotations

import pytest

from onebit.datasets.catalogue import get_scenario
from onebit.pipeline import progress as progress_mod
from onebit.pipeline.progress import RichBar, Silent, Spinner, progress_sink
from onebit.pipeline.runner import run_pipeline
from onebit.pipeline.stages import stages


class Recorder:
    """A ProgressSink that keeps what it was told."""

    def __init__(self) -> None:
        self.events: list[tuple] = []
        self.current = None

    def stage(self, name: str, index: int, total: int) -> None:
        self.current = name
        self.events.append(("stage", name, index, total))

    def step(self, done: int, total: int) -> None:
        self.events.append(("step", self.current, done, total))

    def close(self) -> None:
        self.events.append(("close",))


@pytest.mark.parametrize("scenario, tracker", [("pir14", "intruder"), ("hallway", "findinghumo")])
def test_stages_are_named_in_order_and_long_ones_advance_inside(tmp_path, scenario, tracker):
    data = get_scenario(scenario).write(
        tmp_path / "d", seed=2, duration=40.0, agents=None, drop=0.0, camera=False, params={}
    )
    rec = Recorder()
    res = run_pipeline(data, tmp_path / "run", trackers=(tracker,), progress=rec)
    assert res.status[tracker].startswith("ok")
    names = [st.name for st in stages()]
    assert [e[1] for e in rec.events if e[0] == "stage"] == names
    assert all(e[2] == i and e[3] == len(names) for i, e in enumerate(e for e in rec.events if e[0] == "stage"))
    steps = [e for e in rec.events if e[0] == "step"]
    assert steps and {e[1] for e in steps} == {tracker}  # reported while the tracker's stage runs
    assert [e[2] for e in steps] == sorted(e[2] for e in steps) and steps[-1][2] == steps[-1][3] > 1
    assert rec.events[-1] == ("close",)


def test_quiet_unless_on_a_terminal_and_not_in_ci(monkeypatch):
    monkeypatch.setattr(progress_mod.sys.stderr, "isatty", lambda: True, raising=False)
    monkeypatch.setenv("CI", "1")
    assert isinstance(progress_sink(None), Silent)
    monkeypatch.delenv("CI")
    bar = progress_sink(None)
    assert isinstance(bar, RichBar)
    bar.stage("beams", 3, 10)
    bar.step(5, 10)
    bar.close()
    assert isinstance(progress_sink(False), Silent)
    rec = Recorder()
    assert progress_sink(rec) is rec


def test_simulate_spinner_is_silent_when_not_interactive(capsys):
    with Spinner("simulating", enabled=False) as sp:
        assert sp.p is None
    with Spinner("simulating", enabled=True) as sp:
        assert sp.p is not None
    assert capsys.readouterr().out == ""
