"""Every command block of a tutorial (a ```console fence in docs/tutorials/*.md) runs, in
order, in an empty folder, as the tutorial says: a tutorial that stops working fails here."""

from __future__ import annotations

import os
import re
import stat
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TUTORIALS = sorted(p for p in (ROOT / "docs" / "tutorials").glob("*.md") if p.name != "index.md")
BLOCK = re.compile(r"^```console\n(.*?)^```", re.S | re.M)


def blocks(path: Path) -> list[str]:
    return BLOCK.findall(path.read_text())


def test_every_tutorial_has_commands_and_is_listed():
    assert {p.stem for p in TUTORIALS} >= {"beams", "motion", "frames", "casas", "ceiling"}
    index = (ROOT / "docs" / "tutorials" / "index.md").read_text()
    readme = (ROOT / "README.md").read_text()
    for p in TUTORIALS:
        assert blocks(p), f"{p.name}: no ```console block"
        assert f"({p.name})" in index and f"(docs/tutorials/{p.name})" in readme, p.name


@pytest.mark.parametrize("tutorial", TUTORIALS, ids=lambda p: p.stem)
def test_tutorial_commands_run(tutorial, tmp_path):
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    shim = bin_dir / "onebit"  # `onebit` as the tutorial types it, this checkout's code
    shim.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m onebit.cli "$@"\n')
    shim.chmod(shim.stat().st_mode | stat.S_IXUSR)
    work = tmp_path / "work"
    work.mkdir()
    script = "set -euo pipefail\n" + "\n".join(blocks(tutorial))
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ['PATH']}", RERUN_ANALYTICS="0")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    proc = subprocess.run(["bash", "-c", script], cwd=work, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, (
        f"{tutorial.name}: exit {proc.returncode}\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    )
