"""``phongray grade`` and ``phongray compare``: one image graded against a scene's render or another image;
exit 0 pass, 1 fail, 2 bad input."""

from __future__ import annotations

import argparse
import json
from typing import TYPE_CHECKING, Any

from service.cli.common import (
    CliError,
    budget_of,
    load,
    outgrown_error,
    png_name,
    read,
    read_image,
    remote,
    thresholds,
    write,
)
from service.cli.display import describe
from service.cli.options import Commands, command, limits, no_diagnosis, verdict
from service.cli.options import remote as remote_options

if TYPE_CHECKING:
    from service.images.heatmap import Kind


def _verdict(args: argparse.Namespace, result: dict[str, Any]) -> int:
    """Print a grade (in words, or as JSON with ``--json``); exit 0 for a pass, 1 for a fail."""
    if args.json:
        print(json.dumps(result, indent=1, ensure_ascii=False))
    else:
        print("\n".join(describe(result)))
    return 0 if result["passed"] else 1


def cmd_grade(args: argparse.Namespace) -> int:
    """Exit 0 when the submission passes, 1 when it fails, 2 for bad input."""
    from service.images import grading
    from service.work import pipeline

    thresholds(args)
    png_name(args.heatmap)
    kind: Kind = "raw" if args.raw_heatmap else "verdict"
    heat: bytes | None = None
    text, image = read(args.scene), read_image(args.image)
    if args.server:
        from service.client import post_form

        fields: dict[str, bytes | str] = {
            "scene": text,
            "tolerance": repr(args.tolerance),
            "max_fraction": repr(args.max_fraction),
            "diagnose": "false" if args.no_diagnosis else "true",
        }
        files = {"image": ("submission.png", image, "image/png")}
        with remote(args.scene, args.image):
            result = json.loads(post_form(args.server, "/grade", fields, files, api_key=args.api_key))
            if args.heatmap:
                heat = post_form(
                    args.server, "/grade", fields, files, {"format": "png", "heatmap": kind}, api_key=args.api_key
                )
    else:
        from service.render.rendering import render_pixels
        from tracer import ImageTooLarge, OverBudget, encode_png

        scene = load(args.scene, text)
        try:
            reference = encode_png(render_pixels(scene, budget=budget_of(args, scene)))
        except ImageTooLarge as exc:
            raise CliError(f"{args.scene}: {exc}") from None
        except OverBudget as exc:
            raise outgrown_error(args, exc) from None
        try:
            graded = pipeline.grade_png(
                reference,
                image,
                args.tolerance,
                args.max_fraction,
                kind if args.heatmap else None,
                legend=True,
                explaining=pipeline.Explaining(lambda: scene, pipeline.Checks(diagnose=not args.no_diagnosis)),
            )
        except grading.ImageError as exc:
            raise CliError(f"{args.image}: {exc}") from None
        result, heat = graded.as_dict(), graded.heatmap
    if args.heatmap and heat is not None:
        write(args.heatmap, heat)
    return _verdict(args, result)


def cmd_compare(args: argparse.Namespace) -> int:
    """Two images graded without a scene: exit 0 pass, 1 fail, 2 bad input."""
    from service.images import grading
    from service.work import pipeline

    thresholds(args)
    png_name(args.heatmap)
    reference, image = read_image(args.reference), read_image(args.image)
    try:
        pixels = pipeline.read_reference(reference)
    except grading.ImageError as exc:
        raise CliError(f"{args.reference}: {exc}") from None
    try:
        submitted = pipeline.read_image(image, (pixels.shape[1], pixels.shape[0]))
    except grading.ImageError as exc:
        raise CliError(f"{args.image}: {str(exc).replace('the scene is', 'the reference is')}") from None
    graded = pipeline.compare(
        reference,
        submitted,
        args.tolerance,
        args.max_fraction,
        ("raw" if args.raw_heatmap else "verdict") if args.heatmap else None,
        legend=True,
        reference=pixels,
    )
    if args.heatmap and graded.heatmap is not None:
        write(args.heatmap, graded.heatmap)
    return _verdict(args, graded.as_dict())


def add(sub: Commands) -> None:
    p = command(
        sub,
        "grade",
        "grade a submitted PNG or PPM against the scene's reference render",
        description="Grade a submitted PNG or PPM against the scene's reference render. Exit 0 pass, 1 fail, "
        "2 bad input.",
    )
    p.add_argument("scene", help="scene JSON file")
    p.add_argument("image", help="the submitted PNG or PPM")
    verdict(p)
    no_diagnosis(p)
    limits(p)
    remote_options(p)
    p.set_defaults(func=cmd_grade)

    p = command(
        sub,
        "compare",
        "grade one PNG against another, without a scene",
        description="Grade IMAGE against REFERENCE (two PNGs of one size) as 'grade' would against a "
        "render. Exit 0 pass, 1 fail, 2 bad input.",
    )
    p.add_argument("reference", help="the reference PNG")
    p.add_argument("image", help="the PNG or PPM to grade")
    verdict(p)
    no_diagnosis(p, "accepted as grade accepts it: without a scene, compare never names a likely mistake")
    p.set_defaults(func=cmd_compare)
