"""``phongray serve``: the HTTP service (:mod:`service.http.server`), once its settings and its port are known
to be usable."""

from __future__ import annotations

import argparse
import socket

from service.cli.common import CliError
from service.cli.options import Commands, command, port, positive_int


def cmd_serve(args: argparse.Namespace) -> int:
    from service.settings import Settings

    Settings.from_env()  # a PHONGRAY_* setting of the wrong type is told as itself, before the port is taken
    try:  # a port that cannot be had is one line here, not uvicorn's traceback in a worker
        with socket.create_server((args.host, args.port)):
            pass
    except OSError as exc:
        raise CliError(f"cannot listen on {args.host}:{args.port}: {exc.strerror or exc}") from None
    from service.http.server import serve

    serve(args.host, args.port, args.workers)
    return 0


def add(sub: Commands) -> None:
    p = command(sub, "serve", "run the HTTP service (settings from PHONGRAY_* variables, see docs/service.md)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on")
    p.add_argument("--port", type=port, default=8000, help="port to listen on")
    p.add_argument("--workers", type=positive_int, default=1, help="worker processes")
    p.set_defaults(func=cmd_serve)
