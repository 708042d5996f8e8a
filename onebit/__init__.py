"""onebit: tracking people, animals and robots from one-bit sensors.

Data flows one way: ``readers`` -> canonical polars tables -> ``trackers`` -> tracks ->
``scoring`` -> reports, with ``viz`` writing every stage's output to Rerun recordings.

The public API::

    import onebit

    site = onebit.load_site("data/site.toml")           # validated site model
    res = onebit.run("data", "out", trackers=["beams"])  # the whole pipeline on a dataset folder
    print(res.report)                                    # polars report: stage, metric, value, unit
    res.ok, res.status                                   # did every stage succeed? per-stage status
"""

from __future__ import annotations

import importlib
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # for type checkers only; at run time these names load on first use
    from onebit.core.site import Site, load_site
    from onebit.pipeline.runner import RunResult

__version__ = "0.1.0"

__all__ = ["RunResult", "Site", "__version__", "load_site", "run"]

#: Public names defined in submodules, loaded on first use (PEP 562 module ``__getattr__``).
#: ``import onebit`` then costs nothing: the pipeline -- polars, shapely, scipy, numba, rerun,
#: OpenCV, motmetrics -- is imported when ``onebit.run``/``onebit.load_site`` is first
#: touched, not by every ``import onebit`` (a CLI start-up, a test collecting). This is the
#: one place onebit imports its own modules lazily, by name through ``importlib``, and only
#: for the public API re-exports; every module below imports at its top (the layers contract
#: and ``tests/test_onebit.py`` hold that).
_LAZY = {
    "Site": "onebit.core.site",
    "load_site": "onebit.core.site",
    "RunResult": "onebit.pipeline.runner",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'onebit' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # later lookups skip __getattr__
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))


def run(
    dataset: str | Path,
    out: str | Path,
    *,
    trackers: Iterable[str] | None = None,
    config: Mapping[str, Any] | str | Path | None = None,
    rrd: bool = True,
) -> RunResult:
    """Run the pipeline on a dataset folder and write the run folder ``out``.

    Parameters
    ----------
    dataset : folder with ``site.toml`` and any of the raw logs (README, "The dataset folder").
    out : run folder to write (``tables/``, ``rrd/``, ``report.csv``, ``run.toml``).
    trackers : tracker names (default: every tracker whose inputs exist).
    config : ``run.toml`` sections as a mapping ``{"beams": {"policy": "lifo"}}``, or the path
        of a ``run.toml``.
    rrd : write the Rerun recordings (``out/rrd/``); ``False`` skips them and every viz call
        (the tables and the report are the same): for batch sweeps (``onebit run --no-rrd``).

    Returns
    -------
    RunResult with ``report`` (polars), ``status`` per stage and ``ok``.
    """
    runner = importlib.import_module("onebit.pipeline.runner")  # lazy: see _LAZY
    cfg = runner.load_run_config(config) if isinstance(config, (str, Path)) else dict(config or {})
    return runner.run_pipeline(
        dataset, out, trackers=tuple(trackers) if trackers is not None else None, config=cfg, rrd=rrd
    )
