"""``phongray render``: a scene to a PNG, here, on a ``--server`` or a ``--cluster``, or one pass of it."""

from __future__ import annotations

import argparse
import sys
import time

from service.cli.common import CliError, budget_of, cluster_client, load, outgrown_error, png_name, read, remote, write
from service.cli.display import ProgressBar
from service.cli.options import Commands, command, index, limits, positive_int
from service.cli.options import remote as remote_options

#: tracer.shade.passes.NAMES, here so that the parser needs no tracer import (a test keeps them equal)
PASS_NAMES = (
    "background",
    "ambient",
    "diffuse",
    "specular",
    "reflection",
    "refraction",
    "shadow",
    "normal",
    "depth",
    "object",
)


def cmd_render(args: argparse.Namespace) -> int:
    from service.render.cluster import ClusterError
    from service.render.rendering import BandLost, render_pixels
    from tracer import ImageTooLarge, OverBudget, encode_png

    if args.server and args.cluster:
        raise CliError("--server and --cluster: choose one")
    if args.pass_ is not None or args.light is not None:
        return _render_pass(args)
    png_name(args.output)
    overrides = {"width": args.width, "height": args.height, "samples": args.samples}
    text = read(args.scene)
    started = time.perf_counter()
    if args.server:
        from service.client import post_json

        with remote(args.scene):
            data = post_json(args.server, "/render", text, overrides, api_key=args.api_key)
        write(args.output, data)
        return 0
    scene = load(args.scene, text, overrides)
    budget = budget_of(args, scene)
    bar = ProgressBar()
    try:
        if args.cluster:
            with cluster_client(args) as client:
                pixels = render_pixels(scene, client)
        else:
            pixels = render_pixels(scene, threads=args.threads, progress=bar, processes=True, budget=budget)
    except ImageTooLarge as exc:
        raise CliError(f"{args.scene}: {exc}") from None
    except OverBudget as exc:
        raise outgrown_error(args, exc) from None
    except BandLost as exc:
        raise CliError(f"{args.scene}: {exc}", code=1) from None
    except ClusterError as exc:
        raise CliError(str(exc)) from None
    finally:
        bar.close()
    write(args.output, encode_png(pixels))
    if not args.quiet:
        print(
            f"{args.output}: {pixels.shape[1]}×{pixels.shape[0]} in {time.perf_counter() - started:.3f} s",
            file=sys.stderr,
        )
    return 0


def _render_pass(args: argparse.Namespace) -> int:
    """``render --pass NAME [--light K]``: one pass as a PNG, or its values as ``.npy`` (by the output's name)."""
    from service.render import passes

    if args.pass_ is None:
        raise CliError("--light: only with --pass (the light whose diffuse, specular or shadow is shown)")
    if args.cluster:
        raise CliError("--pass: renders here or on a --server, not on a cluster")
    fmt: passes.Format = "npy" if args.output.lower().endswith(".npy") else "png"
    if fmt == "png":
        png_name(args.output)
    overrides = {"width": args.width, "height": args.height, "samples": args.samples}
    text = read(args.scene)
    started = time.perf_counter()
    if args.server:
        from service.client import post_json

        query = {**overrides, "pass": args.pass_, "light": args.light, "format": fmt}
        with remote(args.scene):
            data = post_json(args.server, "/render", text, query, api_key=args.api_key)
    else:
        from tracer import OverBudget

        scene = load(args.scene, text, overrides)
        try:
            data = passes.encoded(
                args.pass_,
                passes.values(scene, args.pass_, args.light, args.threads, budget=budget_of(args, scene)),
                fmt,
            )
        except ValueError as exc:
            raise CliError(f"{args.scene}: {exc}") from None
        except OverBudget as exc:
            raise outgrown_error(args, exc) from None
    write(args.output, data)
    if not args.quiet:
        of = (
            ""
            if args.pass_ not in passes.OF_A_LIGHT
            else " of every light"
            if args.light is None
            else f" of light {args.light}"
        )
        print(
            f"{args.output}: the {args.pass_} pass{of} ({'values' if fmt == 'npy' else 'PNG'}) in "
            f"{time.perf_counter() - started:.3f} s",
            file=sys.stderr,
        )
    return 0


def add(sub: Commands) -> None:
    p = command(sub, "render", "render a scene to a PNG")
    p.add_argument("scene", help="scene JSON file ('-' for stdin)")
    p.add_argument(
        "-o",
        "--output",
        required=True,
        help="output PNG, *.png ('-' for stdout); with --pass, *.npy writes the pass's values as a NumPy array",
    )
    p.add_argument("--width", type=positive_int, help="image width in pixels (default: the scene's)")
    p.add_argument("--height", type=positive_int, help="image height in pixels (default: the scene's)")
    p.add_argument(
        "--samples", type=positive_int, help="n: an n×n grid of sub-samples per pixel (default: the scene's)"
    )
    p.add_argument("--threads", type=positive_int, help="worker threads (default: all cores)")
    p.add_argument(
        "--pass",
        dest="pass_",
        metavar="NAME",
        choices=PASS_NAMES,
        help="render one pass instead: " + ", ".join(PASS_NAMES) + " (the first six are the image's additive terms)",
    )
    p.add_argument("--light", type=index, metavar="K", help="with --pass: light K alone (its index in lights)")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    limits(p)
    remote_options(p, cluster=True)
    p.set_defaults(func=cmd_render)
