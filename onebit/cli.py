"""The ``onebit`` command line: run, follow, compare, run-many, report, simulate, experiment, import (CASAS, trajectories), logs info / logs convert, init, check, snapshot.

This module builds the parser and runs a command; the commands themselves are in
:mod:`onebit.commands`, one module per group."""

from __future__ import annotations

import argparse
import atexit
import gc
import sys
import tempfile
import traceback

from onebit.commands.experiment import add_experiment_command
from onebit.commands.imports import add_import_commands
from onebit.commands.learn import add_learn_command
from onebit.commands.logs import add_logs_commands
from onebit.commands.run import add_run_commands
from onebit.commands.simulate import add_simulate_command
from onebit.commands.user_data import add_user_data_commands
from onebit.commands.verify import add_verify_path_command
from onebit.core.errors import OnebitError, bounded, is_disk_full
from onebit.pipeline.config_show import add_config_command


def build_parser() -> argparse.ArgumentParser:
    """The ``onebit`` command line: one step per group of subcommands."""
    p = argparse.ArgumentParser(prog="onebit", description="Tracking from one-bit sensors.")
    sub = p.add_subparsers(dest="command", required=True)
    add_run_commands(sub)
    add_simulate_command(sub)
    add_experiment_command(sub)
    add_verify_path_command(sub)
    add_import_commands(sub)
    add_learn_command(sub)
    add_logs_commands(sub)
    add_user_data_commands(sub)
    add_config_command(sub)
    return p


def _skip_the_exit_collection() -> None:
    """At exit, after every other exit handler (they run last registered first): freeze the heap
    so the interpreter's final garbage collection does not walk it. That walk costs 0.2-0.3 s
    after a 10^6-row run (polars, numba, Rerun's classes), a tenth of the run; every file is
    closed by then (recordings flushed, run folders renamed), and the process is ending."""
    gc.freeze()


def main(argv: list[str] | None = None) -> int:
    atexit.unregister(_skip_the_exit_collection)  # once per process, however often main runs
    atexit.register(_skip_the_exit_collection)
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except OnebitError as exc:
        print(f"onebit: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("onebit: interrupted (folders being written were left as they were before)", file=sys.stderr)
        return 130
    except Exception as exc:  # a bug (or the system: disk full): one line, the traceback kept for a bug report
        if is_disk_full(exc):  # not a bug; and no room for a traceback file either
            print(f"onebit: error: no space left on the device: {bounded(str(exc))}", file=sys.stderr)
            return 1
        what = "error" if isinstance(exc, OSError) else "internal error"
        print(f"onebit: {what}: {bounded(f'{type(exc).__name__}: {exc}')}", file=sys.stderr)
        notes = [n for n in getattr(exc, "__notes__", []) if n.startswith("onebit:")]
        if notes:
            print(notes[0], file=sys.stderr)
        else:
            with tempfile.NamedTemporaryFile("w", prefix="onebit-traceback-", suffix=".txt", delete=False) as fh:
                fh.write("".join(traceback.format_exception(exc)))
            print(f"onebit: the traceback is in {fh.name}; please attach it to a bug report", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
