"""Reading back ``.rrd`` files: which entities and stores they hold, and whether they verify.

Used by tests (here and end-to-end) to check recordings without a viewer. Entity paths and
store ids are read with the SDK's :class:`rerun.chunk.RrdReader`; if that is unavailable,
``rerun rrd print --verbose`` output is parsed. :func:`verify` runs ``rerun rrd verify``.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

_CHUNK_LINE = re.compile(r"^Chunk\(.*?\) with \d+ rows \(.*?\) - (?P<path>.+?) - data columns:")
_STORE_ID = re.compile(r'store_id: StoreId\(\s*(?P<kind>\w+),\s*"(?P<app>[^"]*)",\s*"(?P<rec>[^"]*)",\s*\)', re.S)


def rerun_binary() -> Path:
    """The ``rerun`` CLI of this interpreter's environment, else the one on ``PATH``."""
    local = Path(sys.executable).parent / "rerun"
    if local.exists():
        return local
    found = shutil.which("rerun")
    if found is None:
        raise FileNotFoundError(f"no rerun CLI next to {sys.executable} nor on PATH")
    return Path(found)


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(rerun_binary()), *args], capture_output=True, text=True, check=False)


def _clean(path: str) -> str:
    return path.strip().lstrip("/")


#: Root entities of a blueprint store; ``rerun rrd print`` lists them among the recording's.
_BLUEPRINT_ROOTS = {"view", "container", "viewport", "time_panel", "blueprint_panel", "selection_panel", "top_panel"}


def _is_internal(path: str) -> bool:
    return path.startswith("__")


def entity_paths(rrd_path: str | Path) -> set[str]:
    """Entity paths (no leading ``/``, escaped as built by :mod:`onebit.viz.paths`) of the
    first recording store in ``rrd_path``, without Rerun's internal ``__properties``."""
    try:
        from rerun.chunk import RrdReader
    except ImportError:  # pragma: no cover - older SDKs without a reader
        return _entity_paths_cli(rrd_path)
    out = {_clean(c.entity_path) for c in RrdReader(str(rrd_path)).stream()}
    return {p for p in out if p and not _is_internal(p)}


def _entity_paths_cli(rrd_path: str | Path) -> set[str]:
    proc = _run("rrd", "print", "--verbose", str(rrd_path))
    if proc.returncode != 0:
        raise RuntimeError(f"rerun rrd print {rrd_path} failed: {proc.stderr.strip()}")
    found = {_clean(m["path"]) for line in proc.stdout.splitlines() if (m := _CHUNK_LINE.match(line))}
    return {p for p in found if p and not _is_internal(p) and p.split("/")[0] not in _BLUEPRINT_ROOTS}


def store_ids(rrd_path: str | Path) -> list[tuple[str, str]]:
    """``(application_id, recording_id)`` of every recording store in ``rrd_path``."""
    try:
        from rerun.chunk import RrdReader
    except ImportError:  # pragma: no cover - older SDKs without a reader
        return _store_ids_cli(rrd_path)
    return [(s.application_id, s.recording_id) for s in RrdReader(str(rrd_path)).recordings()]


def _store_ids_cli(rrd_path: str | Path) -> list[tuple[str, str]]:
    proc = _run("rrd", "print", str(rrd_path))
    if proc.returncode != 0:
        raise RuntimeError(f"rerun rrd print {rrd_path} failed: {proc.stderr.strip()}")
    ids = [(m["app"], m["rec"]) for m in _STORE_ID.finditer(proc.stdout) if m["kind"] == "Recording"]
    return list(dict.fromkeys(ids))


def verify(rrd_path: str | Path) -> None:
    """Run ``rerun rrd verify``; raise ``RuntimeError`` with its output unless it succeeds."""
    rrd_path = Path(rrd_path)
    if not rrd_path.is_file():
        raise FileNotFoundError(f"no recording at {rrd_path}")
    proc = _run("rrd", "verify", str(rrd_path))
    if proc.returncode != 0:
        raise RuntimeError(
            f"rerun rrd verify {rrd_path} failed (exit {proc.returncode}): {(proc.stderr or proc.stdout).strip()}"
        )
