"""The ``phongray`` command: render, validate, grade, compare, grade-class, autograder, serve, schema.

Every failure a user can cause ends in a one-line message on stderr and a
non-zero exit, never a traceback; ``--server`` gives the same exit codes and
the same messages as local work (both go through :mod:`service.work.pipeline`).
Each group of subcommands is a module of this package, with its options (``add``).
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
from collections.abc import Sequence
from typing import NoReturn

from service.cli import course, grade, render, serve, validate
from service.cli.common import EXIT_BAD_INPUT, CliError
from service.cli.display import ProgressBar
from service.cli.options import Help, Version
from service.cli.render import PASS_NAMES

__all__ = ["PASS_NAMES", "CliError", "ProgressBar", "build_parser", "main", "parse"]


class _OneLine(argparse.ArgumentParser):
    """A parser whose mistakes are one line and exit 2, as every other mistake of the user's is (argparse's own
    prints its whole usage first: fifteen lines of ``grade-class``'s options before the one that says what)."""

    def error(self, message: str) -> NoReturn:
        commands = [a.choices for a in self._actions if isinstance(a, argparse._SubParsersAction)]
        if commands and "required: command" in message:  # (the usage, which lists them, is not printed)
            message += f", one of {', '.join(commands[0])}"
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _OneLine(prog="phongray", description="A reference Phong/Whitted ray tracer.", formatter_class=Help)
    parser.add_argument("-V", "--version", action=Version, help="show the version and exit")
    sub = parser.add_subparsers(dest="command", required=True)
    render.add(sub)
    validate.add(sub)
    grade.add(sub)
    course.add(sub)
    course.add_autograder(sub)
    serve.add(sub)
    sub.add_parser(
        "bench",
        help="run the benchmark (speed, memory, class grading, cluster, HTTP, speed against "
        "error); 'phongray bench --help' for its options",
    )
    validate.add_schema(sub)
    return parser


def _quiet_pipe() -> NoReturn:
    """Standard output was closed early (``phongray schema | head``): stop quietly, as other tools do."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())  # so that the interpreter's own final flush does not fail again
    sys.exit(1)


def parse(argv: Sequence[str]) -> argparse.Namespace:
    """The arguments, with the defaults that come from the settings (``PHONGRAY_CLUSTER``, ...) filled in: read
    only once the command is known, so that ``--version`` and ``--help`` cost no settings."""
    args = build_parser().parse_args(argv)
    if hasattr(args, "cluster_wait"):
        if args.cluster is None and not any(name.upper().startswith("PHONGRAY_") for name in os.environ):
            from service.render.cluster import (
                CLUSTER_WAIT,  # no PHONGRAY_* variable: the settings are their defaults, and
            )

            # a render's start-up need not import pydantic-settings to learn them
            if args.cluster_wait is None:
                args.cluster_wait = CLUSTER_WAIT
            return args
        from service.settings import Settings

        settings = Settings.from_env()
        if args.cluster is None:
            args.cluster = settings.cluster or None
        if args.cluster_wait is None:
            args.cluster_wait = settings.cluster_wait
    return args


def _quiet_dask() -> None:
    """Dask's own log lines (a lost scheduler's reconnection tracebacks) off the terminal: phongray says what
    happened to the cluster in one line of its own."""
    try:
        import distributed  # noqa: F401  (its import sets its loggers' levels: set them after it)
    except ImportError:
        return
    for name in ["distributed", *(n for n in logging.Logger.manager.loggerDict if n.startswith("distributed."))]:
        logging.getLogger(name).setLevel(logging.CRITICAL)


def _settings_error(exc: ValueError) -> int:
    """A PHONGRAY_* variable of the wrong type is one line and exit 2 (any other ValueError is a bug: raised)."""
    from service.settings import SettingsError

    if not isinstance(exc, SettingsError):
        raise exc
    print(f"phongray: {exc}", file=sys.stderr)
    return EXIT_BAD_INPUT


def _interrupted(as_program: bool) -> int:
    """Ctrl-C: one line, status 130; run as the command (``as_program``: its process ends with this call), a
    second Ctrl-C while the pools wind down quits at once (:func:`_quit_now`)."""
    if as_program:  # (not in a caller's process that goes on: a test's, a script's)
        signal.signal(signal.SIGINT, _quit_now)
    if ProgressBar.active is not None:
        ProgressBar.active.close()  # the message goes on a line of its own
    print("phongray: interrupted", file=sys.stderr)
    return 130


def _quit_now(signum: int, frame: object) -> None:
    """A second interrupt, while the first one's exit waits for the worker processes to wind down (their
    current render, a student's run): quit at once, with the same status and no traceback.  What the workers
    leave is theirs to end: a pool's worker exits when it finds its parent gone, a sandboxed run at its limit."""
    os._exit(130)


def main(argv: Sequence[str] | None = None) -> int:
    as_program = argv is None  # (run as the command, whose process ends with this call)
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["bench"]:  # the benchmark has its own options
        from bench.run import main as bench_main

        return bench_main(argv[1:])
    try:
        args = parse(argv)
    except ValueError as exc:
        return _settings_error(exc)
    for stream in (sys.stdout, sys.stderr):  # a scene's text may not be valid Unicode (a lone surrogate)
        if hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="backslashreplace")
    if getattr(args, "cluster", None):
        _quiet_dask()
    try:
        return int(args.func(args))
    except CliError as exc:
        print(f"phongray: {exc}", file=sys.stderr)
        return exc.code
    except ValueError as exc:
        return _settings_error(exc)
    except BrokenPipeError:
        _quiet_pipe()
    except KeyboardInterrupt:
        return _interrupted(as_program)
    except MemoryError:
        print("phongray: out of memory", file=sys.stderr)
        return 1
