"""``phongray validate`` and ``phongray schema``: a scene checked (every problem with its line), the schema
printed."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from service.cli.common import read, remote
from service.cli.options import Commands, command
from service.cli.options import remote as remote_options


def cmd_validate(args: argparse.Namespace) -> int:
    from schemas import SceneError
    from service.work.pipeline import renderable_scene, scene_lines

    text = read(args.scene)
    if args.server:
        from service.client import ServerError, post_json

        try:
            post_json(args.server, "/validate", text, api_key=args.api_key)
        except ServerError as exc:
            if exc.problems is None:
                with remote(args.scene):
                    raise
            lines = scene_lines(args.scene, exc.body["errors"])
        else:
            lines = []
    else:
        try:  # (valid, but beyond what phongray renders, is refused: render and grade-class refuse it)
            _warn_of_limits(args.scene, renderable_scene(args.scene, text))
            lines = []
        except SceneError as exc:
            lines = exc.lines  # type: ignore[attr-defined]
    for line in lines:
        print(line)
    if lines:
        return 1
    print(f"{args.scene}: valid")
    return 0


def _warn_of_limits(name: str, scene: Any) -> None:
    """A warning on stderr for each limit of the service's (its ``PHONGRAY_*`` settings) that the scene exceeds,
    or most likely will as it renders: it is valid, and renders here, but a service would refuse it."""
    from service.admission.limits import beyond_limits
    from service.settings import Settings

    for warning in beyond_limits(scene, Settings.from_env()):
        print(f"{name}: warning: {warning}", file=sys.stderr)


def cmd_schema(args: argparse.Namespace) -> int:
    from schemas import json_schema

    print(json.dumps(json_schema(), indent=2))
    return 0


def add(sub: Commands) -> None:
    p = command(sub, "validate", "check a scene; print every error with its place and line")
    p.add_argument("scene", help="scene JSON file ('-' for stdin)")
    remote_options(p)
    p.set_defaults(func=cmd_validate)


def add_schema(sub: Commands) -> None:
    p = command(sub, "schema", "print the scene JSON Schema")
    p.set_defaults(func=cmd_schema)
