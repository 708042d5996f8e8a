"""Functions the pipeline tests hand to worker processes (``tests/pipeline/test_runner.py``).

A worker imports the module of each function it is sent; defined in the test module, that is
the whole test module (the CLI, rerun's readers, hypothesis, MCAP: seconds a worker); here, a
worker imports polars and the errors.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import polars as pl

from onebit.core.errors import InputError


def where(name: str) -> dict:
    """``{name}_where``: a one-row table of the process that made it."""
    return {f"{name}_where": pl.DataFrame({"pid": [os.getpid()]})}


def bug_run(inputs, site, config):
    """A tracker's run with a bug in it."""
    raise RuntimeError("a bug in the tracker")


def bad_input_run(inputs, site, config):
    """A tracker's run that finds nothing it can use in its inputs."""
    raise InputError("the crossings say nothing this tracker can use")


@dataclass(frozen=True, kw_only=True)
class NoConfig:
    """The configuration of a tracker that takes none."""
