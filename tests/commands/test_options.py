"""Command options take their defaults from the functions and configs the commands call
(onebit.commands.options.default_of), and ``--help`` shows those values."""

from __future__ import annotations

import inspect

import pytest

from onebit.cli import build_parser
from onebit.commands.options import default_of
from onebit.datasets.importers import import_casas
from onebit.datasets.irtracking import import_irtracking
from onebit.pipeline.follow import FollowConfig
from onebit.pipeline.runner import run_pipeline
from onebit.readers.trajectories import TrajectoryFormat
from onebit.trackers.beams.verify import verify_path

#: (command line, option's dest, the function or config field whose default it must be)
CASES = [
    (["import", "casas", "L", "D"], "window", (import_casas, "window_s")),
    (["import", "casas", "L", "D"], "min_count", (import_casas, "min_count")),
    (["import", "casas", "L", "D"], "min_share", (import_casas, "min_share")),
    (["import", "casas", "L", "D"], "spacing", (import_casas, "spacing_m")),
    (["import", "casas", "L", "D"], "hold", (import_casas, "hold_s")),
    (["import", "casas", "L", "D"], "hold_samples", (import_casas, "hold_samples")),
    (["import", "irtracking", "R", "D"], "period", (import_irtracking, "period")),
    (["import", "irtracking", "R", "D"], "radius", (import_irtracking, "radius")),
    (["verify-path", "O", "--story", "a"], "match", (verify_path, "match")),
    (["verify-path", "O", "--story", "a"], "mismatch", (verify_path, "mismatch")),
    (["verify-path", "O", "--story", "a"], "gap", (verify_path, "gap")),
    (["run", "D", "--out", "O"], "cores", (run_pipeline, "cores")),
]


@pytest.mark.parametrize(("argv", "dest", "source"), CASES, ids=lambda c: c if isinstance(c, str) else None)
def test_an_option_defaults_to_what_its_function_uses(argv, dest, source):
    func, name = source
    assert getattr(build_parser().parse_args(argv), dest) == inspect.signature(func).parameters[name].default


def test_config_fields_are_the_defaults_of_follow_and_trajectories():
    follow = build_parser().parse_args(["follow", "D", "--out", "O"])
    assert (follow.poll, follow.idle) == (FollowConfig().poll, FollowConfig().idle)
    traj = build_parser().parse_args(["import", "trajectories", "F", "D"])
    fmt = TrajectoryFormat()
    assert (traj.time_unit, traj.scale, (traj.offset_x, traj.offset_y)) == (fmt.time_unit, fmt.scale, fmt.offset)


def test_help_shows_the_importers_values(capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(["import", "casas", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for option, name in (("transition", "window_s"), ("an edge needs", "min_count"), ("transitions", "min_share")):
        assert f"(default {default_of(import_casas, name):g})" in text, (option, text)


def test_default_of_names_a_parameter_without_one():
    assert default_of(import_casas, "min_share") == inspect.signature(import_casas).parameters["min_share"].default
    with pytest.raises(TypeError, match=r"import_casas\(log=...\) has no default"):
        default_of(import_casas, "log")
