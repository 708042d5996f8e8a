"""``onebit init``: a site.toml skeleton from each kind of log, loadable by the site loader."""

from __future__ import annotations

import numpy as np
import pytest

from onebit.cli import main
from onebit.core.errors import InputError
from onebit.core.site import load_site
from onebit.datasets.skeleton import guess_sensors, init_dataset, log_format

CASAS = """2010-11-04 00:03:50.209589 M003 ON
2010-11-04 00:03:57.399391 M003 OFF
2010-11-04 00:15:08.984841 T002 21.5
2010-11-04 00:30:19.185547 D001 OPEN
2010-11-04 00:30:21.185547 D001 CLOSE
2010-11-04 00:31:00.000000 M004 ON
2010-11-04 00:31:03.000000 M004 OFF
"""


def _write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return p


def _per_second(tmp_path, rows=120, sensors=20, readme=None):
    folder = tmp_path / "aras"
    folder.mkdir()
    rng = np.random.default_rng(0)
    data = np.c_[rng.integers(0, 2, (rows, sensors)), rng.integers(1, 28, (rows, 2))]
    p = folder / "DAY_1.txt"
    np.savetxt(p, data, fmt="%d", delimiter=" ")
    if readme is not None:
        (folder / "README.txt").write_text(readme)
    return p


def _kinds(site_path):
    site = load_site(site_path)
    return site, {m.id: m.type for m in site.motion_sensors}


def test_casas_log(tmp_path):
    log = _write(tmp_path, "data.txt", CASAS)
    assert log_format(log) == "casas"
    path, _ = init_dataset(tmp_path / "ds", [log])
    site, kinds = _kinds(path)
    assert kinds == {"M003": "motion", "T002": "environment", "D001": "contact", "M004": "motion"}
    assert site.ignored == {"T002"}
    assert "# CHECK: guessed from CASAS kind 'temperature'" in path.read_text()


def test_toggle_csv(tmp_path):
    log = _write(tmp_path, "motion.csv", "t,sensor,value\n0,a,1\n2,a,0\n5,bed,1\n905,bed,0\n9,a,1\n11,a,0\n")
    assert log_format(log) == "toggles"
    path, _ = init_dataset(tmp_path / "ds", [log])
    site, kinds = _kinds(path)
    assert kinds == {"a": "motion", "bed": "presence"}  # short ons: a PIR; held 900 s: a level
    assert site.signals == {"a": "edge", "bed": "level"}


def test_wide_and_list_frame_logs(tmp_path):
    wide = _write(tmp_path, "frames.csv", "t,1,2,3\n0.0,0,1,0\n0.5,0,1,1\n")
    lst = _write(tmp_path, "list.csv", "t,active\n0.0,5 6\n0.5,\n1.0,7\n")
    assert (log_format(wide), log_format(lst)) == ("frames-wide", "frames-list")
    path, found = init_dataset(tmp_path / "ds", [wide, lst])
    site, kinds = _kinds(path)
    assert set(kinds) == {"1", "2", "3", "5", "6", "7"}
    assert {b.id for b in site.binary_sensors} == set(kinds)
    assert site.level_sensors == set(kinds)


def test_per_second_file_named_by_position(tmp_path):
    log = _per_second(tmp_path)
    assert log_format(log) == "per-second"
    path, _ = init_dataset(tmp_path / "ds", [log])
    _, kinds = _kinds(path)
    assert list(kinds) == [str(i) for i in range(1, 21)]


def test_per_second_file_named_by_its_readme(tmp_path):
    names = ["Ph1 Photocell Wardrobe", "Ir1 IR Bathroom door", "Fo1 Force sensor Bed", "Co1 Contact sensor Fridge"]
    readme = "Sensors of house A\n" + "".join(
        f"Column {i + 1}: {names[i % 4][:3]}{i}{names[i % 4][3:]}\n" for i in range(20)
    )
    path, _ = init_dataset(tmp_path / "ds", [_per_second(tmp_path, readme=readme)])
    site, kinds = _kinds(path)
    assert list(kinds)[:4] == ["Ph10", "Ir11", "Fo12", "Co13"]
    assert [kinds[k] for k in list(kinds)[:4]] == ["environment", "presence", "presence", "contact"]
    assert "Ph10" in site.ignored


def test_cli_init_refuses_to_replace_and_names_a_bad_log(tmp_path, capsys):
    log = _write(tmp_path, "motion.csv", "t,sensor,value\n0,a,1\n1,a,0\n")
    assert main(["init", str(tmp_path / "ds"), "--from", str(log)]) == 0
    assert "CHECK" in capsys.readouterr().out
    assert main(["init", str(tmp_path / "ds"), "--from", str(log)]) == 2
    assert "--force" in capsys.readouterr().err
    bad = _write(tmp_path, "notes.txt", "hello world\n")
    with pytest.raises(InputError) as exc:
        guess_sensors(bad)
    assert "notes.txt:1" in str(exc.value)
