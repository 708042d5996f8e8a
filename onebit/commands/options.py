"""Options and helpers shared by several commands."""

from __future__ import annotations

import argparse
import inspect
from collections.abc import Callable
from typing import Any

from onebit.pipeline.executors import EXECUTORS, make_executor


def default_of(func: Callable, name: str) -> Any:
    """The default of ``func``'s parameter ``name``: a command option's one source, so that
    ``--help`` and the command show the value the function uses."""
    default = inspect.signature(func).parameters[name].default
    if default is inspect.Parameter.empty:
        raise TypeError(f"{func.__qualname__}({name}=...) has no default")
    return default


def tracker_names(text: str | None) -> tuple[str, ...] | None:
    """``--trackers a,b``: the names, or ``None`` (every tracker) when not given."""
    return tuple(t.strip() for t in text.split(",")) if text else None


def executor(args):
    """The executor of ``--executor/--workers/--ray-address`` (run-many, experiment)."""
    return make_executor(args.executor, workers=args.workers, address=args.ray_address)


def add_executor_options(p: argparse.ArgumentParser) -> None:
    """``--executor``, ``--workers`` and ``--ray-address`` (run-many, experiment)."""
    p.add_argument(
        "--executor",
        choices=EXECUTORS,
        default=default_of(make_executor, "kind"),
        help="where the tasks run: serial (this process), local (a process pool) or ray (default %(default)s)",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        help="processes of the local pool / CPUs of a local Ray instance (default: one per core); "
        "with --ray-address: at most N tasks at a time (default: the cluster's CPUs)",
    )
    p.add_argument(
        "--ray-address",
        default=None,
        metavar="ADDR",
        help="join a running Ray cluster (e.g. auto or HEAD:6379; see 'ray start --head'); "
        "default: start a local Ray instance",
    )
