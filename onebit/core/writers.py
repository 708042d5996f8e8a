"""Atomic output writing for run folders, datasets and studies: every file is written to a
temporary file in the same folder and renamed over its target only when complete
(:func:`atomic_path`), so an interrupted run never leaves a half-written file. This is the
one place that does it; every writer of onebit goes through it."""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import polars as pl


def temp_path(path: str | Path, *, suffix: str = ".tmp") -> Path:
    """The temporary sibling of ``path`` a writer fills before the rename:
    ``.<name>.<pid><suffix>`` (``suffix`` may keep an extension a library needs, e.g. ``.tmp.mp4``)."""
    path = Path(path)
    return path.with_name(f".{path.name}.{os.getpid()}{suffix}")


def commit(tmp: str | Path, path: str | Path) -> Path:
    """Rename the finished temporary file ``tmp`` over ``path`` (atomic on one file system)."""
    os.replace(tmp, path)
    return Path(path)


@contextmanager
def atomic_path(path: str | Path, *, suffix: str = ".tmp") -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success rename it over ``path``, on any
    error delete it and re-raise (``path`` keeps its old content, if any)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = temp_path(path, suffix=suffix)
    try:
        yield tmp
        commit(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_parquet(df: pl.DataFrame, path: str | Path) -> None:
    with atomic_path(path) as tmp:
        df.write_parquet(tmp)


def write_csv(df: pl.DataFrame, path: str | Path) -> None:
    with atomic_path(path) as tmp:
        df.write_csv(tmp)


def write_text(text: str, path: str | Path) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def copy_file(src: str | Path, dst: str | Path) -> None:
    """Copy ``src`` to ``dst`` atomically."""
    with atomic_path(dst) as tmp:
        shutil.copyfile(src, tmp)


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    s = str(v).replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")
    return f'"{s}"'


def to_toml(data: dict[str, Any]) -> str:
    """Serialise a two-level mapping (scalars/lists at the top, tables of scalars/lists below)."""
    lines = [f"{k} = {_toml_value(v)}" for k, v in data.items() if not isinstance(v, dict)]
    for k, v in data.items():
        if isinstance(v, dict):
            lines.append(f"\n[{k}]")
            for kk, vv in v.items():
                if isinstance(vv, dict):
                    continue
                lines.append(f"{_key(kk)} = {_toml_value(vv)}")
            for kk, vv in v.items():
                if isinstance(vv, dict):
                    lines.append(f"\n[{k}.{_key(kk)}]")
                    lines += [f"{_key(a)} = {_toml_value(b)}" for a, b in vv.items()]
    return "\n".join(lines) + "\n"


def _key(k: str) -> str:
    return k if k.replace("_", "").replace("-", "").isalnum() else f'"{k}"'
