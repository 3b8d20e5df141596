"""The parser's shared parts: the types of option values, the help that shows defaults, ``--version``, and the
groups of options several commands take (a server, a cluster, limits, the grading thresholds)."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from importlib.metadata import PackageNotFoundError, version
from typing import Any


def positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < 1:
        raise argparse.ArgumentTypeError("must be ≥ 1")
    return value


def _version() -> str:
    try:
        return version("phongray")
    except PackageNotFoundError:  # run from a source tree that was never installed
        return "unknown (not installed)"


class Version(argparse.Action):
    """``--version``, looked up only when asked for (reading package metadata costs every command 30 ms)."""

    def __init__(self, option_strings: Sequence[str], dest: str = argparse.SUPPRESS, help: str | None = None):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, help=help)

    def __call__(self, parser: argparse.ArgumentParser, namespace: Any, values: Any, option: str | None = None) -> None:
        print(f"phongray {_version()}")
        parser.exit()


class Help(argparse.HelpFormatter):
    """Help that shows each option's default, unless it has none or its text already says it."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if "(default" in text or action.default in (None, False, argparse.SUPPRESS) or not action.option_strings:
            return text
        return text + " (default: %(default)s)"


def _integer(text: str, low: int, high: int | None, what: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < low or (high is not None and value > high):
        raise argparse.ArgumentTypeError(f"{value} is not {what}")
    return value


def index(text: str) -> int:
    return _integer(text, 0, None, "an index (0, 1, ...)")


def port(text: str) -> int:
    return _integer(text, 0, 65535, "a TCP port (0–65535)")


#: the longest wait an option takes (a week; a run's wall time too): beyond, a timer's deadline overflows the
#: platform's time
MOST_WAIT = 7 * 24 * 3600.0


def seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not value >= 0:
        raise argparse.ArgumentTypeError("must be ≥ 0")
    if not value <= MOST_WAIT:
        raise argparse.ArgumentTypeError(f"{text!r}: must be at most {MOST_WAIT:g} (a week)")
    return value


def remote(p: argparse.ArgumentParser, cluster: bool = False) -> None:
    p.add_argument(
        "--server",
        metavar="URL",
        help="send the work to a running phongray service (http:// is assumed when the URL has no scheme)",
    )
    p.add_argument(
        "--api-key",
        metavar="KEY",
        default=None,
        help="the service's API key, for --server (default: $PHONGRAY_API_KEY)",
    )
    if cluster:
        p.add_argument(
            "--cluster",
            metavar="tcp://HOST:PORT",
            help="run the work on this Dask scheduler's cluster (default: $PHONGRAY_CLUSTER; "
            "needs 'phongray[cluster]')",
        )
        p.add_argument(
            "--cluster-wait",
            metavar="SECONDS",
            type=seconds,
            help="how long to wait for the cluster's first worker before giving up "
            "(default: $PHONGRAY_CLUSTER_WAIT, else 30)",
        )


def limits(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--limits",
        action="store_true",
        help="hold the scene to the service's limits (PHONGRAY_* settings: pixels, samples, depth, "
        "the cost counted as it renders, render_timeout for grade-class), as a server would; "
        "without it a scene here is trusted",
    )


def thresholds(p: argparse.ArgumentParser) -> None:
    p.add_argument("--tolerance", type=float, default=2.0, help="8-bit levels a pixel may differ by (0–255)")
    p.add_argument(
        "--max-fraction",
        type=float,
        default=0.001,
        help="fraction of pixels that may be off even against their 3×3 neighbourhood (0–1)",
    )


def no_diagnosis(p: argparse.ArgumentParser, what: str = "") -> None:
    p.add_argument(
        "--no-diagnosis",
        action="store_true",
        help=what
        or "skip naming the likely mistake of a failing image (it renders the scene once per classic mistake)",
    )


def verdict(p: argparse.ArgumentParser) -> None:
    thresholds(p)
    p.add_argument(
        "--heatmap",
        metavar="OUT.png",
        help="write the heat-map here: the pixels that decided the verdict, brighter and darker, with a legend",
    )
    p.add_argument("--raw-heatmap", action="store_true", help="draw the plain difference in the heat-map instead")
    p.add_argument("--json", action="store_true", help="print the grade as JSON (the numbers of /grade)")


Commands = Any
"""The subparsers action of ``phongray`` (argparse's private ``_SubParsersAction``)."""


def command(sub: Commands, name: str, help: str, **kw: Any) -> argparse.ArgumentParser:
    """A subcommand's parser, described by its help (capitalised, with a full stop) unless given its own."""
    return sub.add_parser(
        name, help=help, description=kw.pop("description", help[0].upper() + help[1:] + "."), formatter_class=Help, **kw
    )
