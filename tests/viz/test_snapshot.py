"""``onebit snapshot``: a run's recordings rendered headless to PNGs, any tab."""

from __future__ import annotations

import pytest

from onebit.cli import main
from onebit.core.errors import InputError
from onebit.datasets.hallway_sim import write_hallway_dataset
from onebit.pipeline.runner import run_pipeline
from onebit.viz.snapshot import RenderError, choose_tab, snapshot, tabs, vulkan_problem

PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def two_tab_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("snap")
    data = write_hallway_dataset(root / "data", seed=1, duration=20.0, users=2)
    return run_pipeline(data, root / "run", trackers=["findinghumo", "hmm1"]).out


def test_a_named_tab_renders_to_a_png(two_tab_run, tmp_path):
    problem = vulkan_problem()
    if problem is not None:
        pytest.skip(f"no Vulkan driver here: {problem}")
    out = tmp_path / "png"
    assert main(["snapshot", str(two_tab_run), "--at", "10", "--view", "hmm1", "--out", str(out)]) == 0
    (png,) = out.glob("*.png")
    assert png.name == "hmm1-decoded-paths-t10.png"
    data = png.read_bytes()
    assert data.startswith(PNG) and len(data) > 20_000  # a drawn viewer, not an empty image


def test_without_a_driver_it_says_what_to_install(two_tab_run, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("VK_ICD_FILENAMES", str(tmp_path / "none.json"))
    problem = vulkan_problem()
    if problem is None:
        pytest.skip("this system does not read VK_ICD_FILENAMES (not Linux)")
    assert "mesa-vulkan-drivers" in problem
    with pytest.raises(RenderError, match="mesa-vulkan-drivers"):
        snapshot(two_tab_run, [1.0], tmp_path / "png")
    assert main(["snapshot", str(two_tab_run), "--at", "1", "--out", str(tmp_path / "png")]) == 2
    assert "apt-get install mesa-vulkan-drivers" in capsys.readouterr().err
    assert not list(tmp_path.rglob("*.png"))


def test_a_run_without_recordings_is_an_input_error(tmp_path):
    (tmp_path / "run").mkdir()
    with pytest.raises(InputError, match="no Rerun recordings"):
        snapshot(tmp_path / "run", [1.0], tmp_path / "png")


def test_tabs_are_found_and_chosen_by_name():
    bp = {
        "/container/top": {
            "ContainerBlueprint": {"container_kind": "Tabs", "contents": ["container/a", "container/b"]}
        },
        "/container/a": {"ContainerBlueprint": {"container_kind": "Horizontal", "display_name": "hmm1: decoded paths"}},
        "/container/b": {"ContainerBlueprint": {"container_kind": "Horizontal", "display_name": "hmm2: decoded paths"}},
    }
    found = tabs(bp)
    assert found == {"hmm1: decoded paths": "container/a", "hmm2: decoded paths": "container/b"}
    assert choose_tab(list(found), "HMM2") == "hmm2: decoded paths"
    with pytest.raises(InputError, match="several tabs"):
        choose_tab(list(found), "hmm")
    with pytest.raises(InputError, match="'hmm1: decoded paths'"):
        choose_tab(list(found), "beams")
