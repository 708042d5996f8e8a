"""Atomic output writing for run folders, datasets and studies: every file is written to a
temporary file in the same folder and renamed over its target only when complete
(:func:`atomic_path`), so an interrupted run never leaves a half-written file. This is the
one place that does it; every writer of onebit goes through it.

A whole folder is replaced the same way (:func:`folder_transaction`): its new entries are
written into a fresh work folder inside it and swapped in when complete, so the folder holds
either its previous complete content or the new one -- or, if a process dies during the
swap itself, an ``INCOMPLETE`` marker that says so. Temporary files and work folders of
processes that died are removed (:func:`remove_stale_temps`, :func:`folder_transaction`).
"""

from __future__ import annotations

import fcntl
import os
import re
import shutil
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import polars as pl

from onebit.core.errors import DiskFullError, InputError, is_disk_full

#: Name of the marker file of a folder whose entries are being swapped (or whose swap was cut).
INCOMPLETE = "INCOMPLETE"
#: Prefix of the work folder (``.onebit-work-<pid>``) and of the folder holding the entries
#: being replaced (``.onebit-old-<pid>``) inside a folder under :func:`folder_transaction`.
WORK_PREFIX = ".onebit-work-"
OLD_PREFIX = ".onebit-old-"
_TEMP_NAME = re.compile(r"^\.(?P<name>.+)\.(?P<pid>\d+)(?:\.tmp(?:\.[^.]+)?|\.partial)$")


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
    error delete it and re-raise (``path`` keeps its old content, if any).

    A full disk (``ENOSPC``/``EDQUOT``, or a library's "No space left on device") becomes a
    :class:`~onebit.core.errors.DiskFullError` naming ``path``: one clear line, the half-written
    temporary file removed, every file written before untouched."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        if is_disk_full(exc):
            raise DiskFullError(path) from exc
        raise
    tmp = temp_path(path, suffix=suffix)
    try:
        yield tmp
        commit(tmp, path)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if isinstance(exc, Exception) and not isinstance(exc, DiskFullError) and is_disk_full(exc):
            raise DiskFullError(path) from exc
        raise


#: Logical bytes of a Parquet row group at most (see :func:`write_parquet`).
ROW_GROUP_BYTES = 64 * 2**20


def write_parquet(df: pl.DataFrame, path: str | Path) -> None:
    """``df`` to ``path`` atomically, in row groups of at most :data:`ROW_GROUP_BYTES` of
    logical data (polars' default of 512^2 rows per group is encoded whole in memory: a
    table of 3 kB WKB regions, 226 000 rows, held 0.7 GB more while it was written)."""
    rows = None
    if df.height:
        per_row = max(df.estimated_size() / df.height, 1.0)
        rows = max(1024, int(ROW_GROUP_BYTES / per_row))
    with atomic_path(path) as tmp:
        if rows is not None and rows < df.height:
            df.write_parquet(tmp, row_group_size=rows)
        else:
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


# --------------------------------------------------------------------------- stale temporaries


def pid_alive(pid: int) -> bool:
    """Whether a process ``pid`` exists (one of another user counts as alive)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_stale_temps(folder: str | Path) -> list[Path]:
    """Delete the temporary files (:func:`temp_path` names: ``.<name>.<pid>.tmp``,
    ``.<name>.<pid>.partial``, ...) under ``folder`` whose process no longer runs.

    Returns the files removed. A file of a live process (or of another user's) is kept.
    """
    folder = Path(folder)
    removed: list[Path] = []
    if not folder.is_dir():
        return removed
    for root, _dirs, files in os.walk(folder):
        for name in files:
            m = _TEMP_NAME.match(name)
            if m and int(m["pid"]) != os.getpid() and not pid_alive(int(m["pid"])):
                p = Path(root) / name
                p.unlink(missing_ok=True)
                removed.append(p)
    return removed


# --------------------------------------------------------------------------- folder transactions


@contextmanager
def folder_lock(folder: str | Path) -> Iterator[None]:
    """Hold an exclusive lock on ``folder`` (``flock`` on the folder itself; released when the
    process ends, however it ends). Another process holding it is an :class:`InputError`."""
    folder = Path(folder)
    fd = os.open(folder, os.O_RDONLY)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise InputError(
                "another onebit process is writing this folder; wait for it to finish", file=folder
            ) from None
        except OSError:  # a file system without locks (some network mounts): go on unlocked
            pass
        yield
    finally:
        os.close(fd)


def _work_debris(folder: Path) -> list[Path]:
    return [p for p in folder.iterdir() if p.name.startswith((WORK_PREFIX, OLD_PREFIX))]


def prepare_folder(folder: str | Path) -> Path:
    """Create ``folder`` (and its parents) for writing; an existing file there, or a folder
    that cannot be created, is an :class:`InputError` naming it."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise InputError("exists and is not a folder; give a folder to write into", file=folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the folder: {exc.strerror or exc}", file=folder) from None
    return folder


@contextmanager
def folder_transaction(folder: str | Path, *, replaces: Callable[[str], bool] = lambda name: True) -> Iterator[Path]:
    """Replace entries of ``folder`` as one transaction: yield a fresh, empty work folder
    (``folder/.onebit-work-<pid>``) to write into; when the block succeeds, the entries of
    ``folder`` that ``replaces(name)`` selects are replaced by the work folder's entries.

    Protocol (every step a rename inside ``folder``, so one file system):

    1. lock ``folder`` (:func:`folder_lock`); remove work folders and temporary files that
       dead processes left (the lock says no live process is using them);
    2. the caller writes everything into the work folder; on any error the work folder is
       deleted and ``folder`` is untouched;
    3. on success: write ``folder/INCOMPLETE``, move the replaced entries into
       ``.onebit-old-<pid>``, move the new entries in, delete ``INCOMPLETE`` (the commit
       point), delete the old entries.

    So at any moment ``folder`` holds its previous entries, or the new ones, or is marked
    ``INCOMPLETE`` (a process killed during step 3); never a mixture without the marker.
    The work and old folders (``.onebit-work-*``, ``.onebit-old-*``) are never replaced.
    """
    folder = prepare_folder(folder)
    with folder_lock(folder):
        for debris in _work_debris(folder):
            shutil.rmtree(debris, ignore_errors=True)
        remove_stale_temps(folder)
        work = folder / f"{WORK_PREFIX}{os.getpid()}"
        work.mkdir()
        try:
            yield work
        except BaseException:
            shutil.rmtree(work, ignore_errors=True)
            raise
        _swap_in(folder, work, replaces)


def _swap_in(folder: Path, work: Path, replaces: Callable[[str], bool]) -> None:
    marker = folder / INCOMPLETE
    write_text(
        "This folder is incomplete: onebit was interrupted while it replaced the folder's\n"
        "previous content with a new one, so it may hold a mixture of both. Write it again\n"
        "(the same onebit command); onebit refuses to read it until then.\n",
        marker,
    )
    old = folder / f"{OLD_PREFIX}{os.getpid()}"
    old.mkdir(exist_ok=True)
    new_names = {p.name for p in work.iterdir()}
    for entry in sorted(folder.iterdir()):
        if entry.name.startswith((WORK_PREFIX, OLD_PREFIX)) or entry.name == INCOMPLETE:
            continue
        if replaces(entry.name) or entry.name in new_names:
            os.replace(entry, old / entry.name)
    for entry in sorted(work.iterdir()):
        os.replace(entry, folder / entry.name)
    marker.unlink()
    shutil.rmtree(old, ignore_errors=True)
    shutil.rmtree(work, ignore_errors=True)


def is_incomplete(folder: str | Path) -> bool:
    """Whether ``folder`` carries the ``INCOMPLETE`` marker of a cut :func:`folder_transaction`."""
    return (Path(folder) / INCOMPLETE).exists()


def in_progress(folder: str | Path) -> bool:
    """Whether ``folder`` holds a work folder of a :func:`folder_transaction` (running or dead)."""
    folder = Path(folder)
    return folder.is_dir() and any(p.name.startswith(WORK_PREFIX) for p in folder.iterdir())
