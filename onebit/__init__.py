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

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from onebit.core.site import Site, load_site
from onebit.pipeline.runner import RunResult, load_run_config, run_pipeline

__version__ = "0.1.0"

__all__ = ["RunResult", "Site", "__version__", "load_site", "run"]


def run(
    dataset: str | Path,
    out: str | Path,
    *,
    trackers: Iterable[str] | None = None,
    config: Mapping[str, Any] | str | Path | None = None,
) -> RunResult:
    """Run the pipeline on a dataset folder and write the run folder ``out``.

    Parameters
    ----------
    dataset : folder with ``site.toml`` and any of the raw logs (README, "The dataset folder").
    out : run folder to write (``tables/``, ``rrd/``, ``report.csv``, ``run.toml``).
    trackers : tracker names (default: every tracker whose inputs exist).
    config : ``run.toml`` sections as a mapping ``{"beams": {"policy": "lifo"}}``, or the path
        of a ``run.toml``.

    Returns
    -------
    RunResult with ``report`` (polars), ``status`` per stage and ``ok``.
    """
    cfg = load_run_config(config) if isinstance(config, (str, Path)) else dict(config or {})
    return run_pipeline(dataset, out, trackers=tuple(trackers) if trackers is not None else None, config=cfg)
