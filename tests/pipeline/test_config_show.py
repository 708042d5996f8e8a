"""``onebit config show [STAGE]``: every parameter of every run.toml section, as TOML that reads
back as the defaults."""

from __future__ import annotations

import tomllib

import pytest

from onebit.cli import main
from onebit.core.config import config_from_mapping
from onebit.core.params import describe
from onebit.pipeline.config_show import config_sections, show, toml_value


def test_every_section_reads_back_as_its_defaults():
    sections = config_sections()
    assert {"motion", "proximity", "occupancy", "correct", "scores", "binpf", "intruder", "beams"} <= set(sections)
    data = tomllib.loads(show())
    assert set(data) == set(sections)
    for name, cls in sections.items():
        assert config_from_mapping(cls, data[name], section=name) == cls(), name


def test_every_parameter_is_shown_with_its_doc_and_what_is_allowed():
    text = show("binpf")
    for p in describe(config_sections()["binpf"]):
        line = f"# {p.name} =" if p.default is None else f"{p.name} = "
        assert f"\n{line}" in text, p.name
    assert (
        "# footprint radius R_s for every sensor; unset = each sensor's r_outer.\n# (float, m, [1e-09, 1000000000.0], may be unset)\n# radius =\n"
        in text
    )
    assert "# (int, [1, 1000000])\nparticles = 300\n" in text


def test_toml_values():
    assert [toml_value(v) for v in (True, 3, 0.5, 'a"b', (1.0, 2.0), {}, {"a b": 1}, float("inf"))] == [
        "true",
        "3",
        "0.5",
        '"a\\"b"',
        "[1.0, 2.0]",
        "{}",
        '{ "a b" = 1 }',
        "inf",
    ]


def test_the_command_prints_one_stage_or_names_the_known_ones(capsys):
    assert main(["config", "show", "scores"]) == 0
    out = capsys.readouterr().out
    assert "[scores]" in out and "crossing_tolerance_s = 1.0" in out and "[binpf]" not in out
    assert main(["config", "show", "nope"]) == 2
    err = capsys.readouterr().err
    assert "no stage 'nope' takes a config" in err and "'binpf'" in err


@pytest.mark.parametrize("stage", sorted(config_sections()))
def test_every_stage_shows(stage):
    assert tomllib.loads(show(stage)).keys() == {stage}
