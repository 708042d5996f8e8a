"""Opening and closing ``.rrd`` files atomically.

A recording is written to a temp file next to its final path and renamed into place only
when it is complete, so an interrupted run never leaves a half ``.rrd`` (docs/architecture.md,
"Standards"). Every stage of a run writes its own file ``OUT/rrd/<stage>.rrd`` with the same
application id and recording id, so opening them together overlays them in one recording.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

from onebit.core import writers
from onebit.core.errors import OnebitError
from onebit.core.lazy import lazy_module, quiet_import

rr = lazy_module("rerun")

#: Application id of every onebit recording.
APPLICATION_ID = "onebit"


_ENV_LOCK = threading.RLock()
_ARROW = {"checked": False}


def arrow_without_pandas() -> None:
    """Keep pyarrow from importing pandas (0.3-0.4 s, a third of a short run's recordings)
    when it first converts a numpy array -- which every Rerun log call does: pyarrow asks
    whether the array is a pandas one, and to ask, imports pandas. onebit never hands pandas
    objects to Rerun, so unless pandas is in the process already, pyarrow's one lazy check
    is made here while ``import pandas`` fails: pyarrow then records that there is no pandas
    for those checks. Whatever asks pyarrow for pandas explicitly later (``to_pandas``)
    imports it as usual (pyarrow retries the import then); a module that imports pandas
    itself (motmetrics) is not affected. Called by :func:`open_recording`; once per process."""
    if _ARROW["checked"]:
        return
    _ARROW["checked"] = True
    if "pandas" in sys.modules:  # already paid for
        return
    import numpy as np
    import pyarrow as pa

    blocker = _NoPandas()
    sys.meta_path.insert(0, blocker)  # ``import pandas`` raises ImportError
    try:
        pa.array(np.zeros(1))  # pyarrow's lazy pandas check: "not installed", once
    finally:
        sys.meta_path.remove(blocker)


class _NoPandas:
    """A meta path finder refusing pandas (used by :func:`arrow_without_pandas` only)."""

    def find_spec(self, name, path=None, target=None):
        if name == "pandas" or name.startswith("pandas."):
            raise ImportError(f"{name} is not imported for pyarrow's array checks (onebit.viz)")
        return None


def import_rerun() -> None:
    """Import Rerun (once per process) with the cyclic garbage collector paused and its objects
    frozen (:func:`onebit.core.lazy.collector_paused`): its import makes some 10^5 objects (an
    attrs class per component and archetype), all kept, and the collections they trigger
    (about 80, one of them over the whole heap) find nothing to free -- 0.02-0.05 s of the
    0.2-0.25 s import. Called by :func:`open_recording`."""
    quiet_import("rerun")


@contextlib.contextmanager
def rerun_enabled() -> Iterator[None]:
    """Rerun's ``RERUN`` environment variable (``RERUN=0``/``off``) turns its logging off in the
    whole process, and a disabled stream writes no file. onebit only writes files (nothing
    is streamed or spawned), so its recordings are written regardless: inside this block the
    variable is ``1`` (the SDK reads it when a stream is created); it is restored after.
    :func:`open_recording` uses it; the runner holds it around a whole run (blueprints too)."""
    with _ENV_LOCK:
        old = os.environ.get("RERUN")
        if old is None:
            yield
            return
        os.environ["RERUN"] = "1"
        try:
            yield
        finally:
            os.environ["RERUN"] = old


def temp_path(path: str | Path) -> Path:
    """The temp file a recording for ``path`` is written to before the rename."""
    return writers.temp_path(path, suffix=".partial")


def open_recording(path: str | Path, *, recording_id: str, application_id: str = APPLICATION_ID) -> rr.RecordingStream:
    """A new recording stream saving to a temp file next to ``path``.

    Nothing is spawned and no network is used. Finish with :func:`close_recording`, which
    renames the temp file to ``path``; or use :func:`stage_recording`.
    """
    if not recording_id:
        raise ValueError(f"recording_id must be a non-empty string, got {recording_id!r}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    import_rerun()
    arrow_without_pandas()
    with rerun_enabled():
        rec = rr.RecordingStream(application_id, recording_id=recording_id)
        rec.save(temp_path(path))
    if not rec.is_enabled():  # pragma: no cover - only if the SDK stops honouring the override
        raise OnebitError(
            f"{path}: Rerun logging is turned off in this process (RERUN={os.environ.get('RERUN')!r}), "
            "so no recording can be written; unset RERUN"
        )
    return rec


def close_recording(rec: rr.RecordingStream, path: str | Path) -> Path:
    """Flush ``rec``, close its file and atomically rename the temp file to ``path``."""
    path = Path(path)
    rec.flush()
    rec.disconnect()
    tmp = temp_path(path)
    if not tmp.exists():
        raise OnebitError(f"{path}: Rerun wrote no recording (its temporary file {tmp.name} is missing)")
    return writers.commit(tmp, path)


def discard_recording(rec: rr.RecordingStream, path: str | Path) -> None:
    """Close ``rec`` and delete its temp file; ``path`` is left untouched."""
    rec.disconnect()
    temp_path(path).unlink(missing_ok=True)


def stage_path(out_dir: str | Path, stage: str) -> Path:
    """``OUT/rrd/<stage>.rrd``."""
    return Path(out_dir) / "rrd" / f"{stage}.rrd"


@contextlib.contextmanager
def stage_recording(
    out_dir: str | Path, stage: str, recording_id: str, *, application_id: str = APPLICATION_ID
) -> Iterator[rr.RecordingStream]:
    """Record one stage into ``OUT/rrd/<stage>.rrd``; the file appears only if the block succeeds.

    Examples
    --------
    >>> with stage_recording(out, "beams", run_id) as rec:   # doctest: +SKIP
    ...     log_site(rec, site, region_graph)
    """
    path = stage_path(out_dir, stage)
    rec = open_recording(path, recording_id=recording_id, application_id=application_id)
    try:
        yield rec
    except BaseException:
        discard_recording(rec, path)
        raise
    close_recording(rec, path)
