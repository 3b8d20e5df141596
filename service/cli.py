"""The ``phongray`` command: render, validate, grade, compare, grade-class, serve, schema.

Every failure a user can cause ends in a one-line message on stderr and a
non-zero exit, never a traceback; ``--server`` gives the same exit codes and
the same messages as local work (both go through :mod:`service.pipeline`).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

from .display import ProgressBar, counted, describe, printable

#: tracer.passes.NAMES, here so that the parser needs no tracer import (a test keeps them equal)
PASS_NAMES = ("background", "ambient", "diffuse", "specular", "reflection", "refraction", "shadow", "normal",
              "depth", "object")

if TYPE_CHECKING:
    from tracer.budget import OverBudget

    from .heatmap import Kind

EXIT_BAD_INPUT = 2
__all__ = ["ProgressBar", "build_parser", "main"]


class CliError(Exception):
    """A user-facing failure: printed as one line, exit code attached."""

    def __init__(self, message: str, code: int = EXIT_BAD_INPUT):
        super().__init__(message)
        self.code = code


def _read(path: str) -> bytes:
    try:
        return sys.stdin.buffer.read() if path == "-" else Path(path).read_bytes()
    except OSError as exc:
        raise CliError(f"{path}: cannot read: {exc.strerror or exc}") from None


def _read_image(path: str) -> bytes:
    """An image file, read no further than the limit ``max_image_bytes`` (an image is a student's file: a file
    without end, such as /dev/zero, must not be read whole), the same with and without ``--server``."""
    import stat

    from .classgrade.untrusted import file_kind
    from .settings import Settings

    limit = Settings.from_env().max_image_bytes
    try:
        # opened without blocking, and looked at once open: a FIFO or a socket, which would wait for a writer
        # that never comes, is refused; a device without end (/dev/zero) is read up to the limit
        with os.fdopen(os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0)), "rb") as f:
            mode = os.fstat(f.fileno()).st_mode
            if stat.S_ISFIFO(mode) or stat.S_ISSOCK(mode):
                raise CliError(f"{path}: {file_kind(mode)}")
            data = f.read(limit + 1)
    except OSError as exc:
        raise CliError(f"{path}: cannot read: {exc.strerror or exc}") from None
    if len(data) > limit:
        raise CliError(f"{path}: larger than the limit max_image_bytes = {limit} bytes (PHONGRAY_MAX_IMAGE_BYTES)")
    return data


def _write(path: str, data: bytes) -> None:
    try:
        if path == "-":
            sys.stdout.buffer.write(data)
            sys.stdout.flush()
        else:
            _replace(Path(path), data)
    except BrokenPipeError:
        raise
    except OSError as exc:
        raise CliError(f"{path}: cannot write: {exc.strerror or exc}") from None


def _replace(path: Path, data: bytes) -> None:
    """Write a file whole or not at all: a temporary file in its folder, then one rename, so that a failure (a
    full disk, an interruption) never leaves a truncated image where an old one was.  The file keeps its mode;
    a symbolic link is written through; a device or a FIFO (``/dev/null``) is written to as it is."""
    import stat

    target = path.resolve() if path.is_symlink() else path
    try:
        mode: int | None = os.stat(target).st_mode
    except FileNotFoundError:
        mode = None
    if mode is not None and not stat.S_ISREG(mode):
        target.write_bytes(data)
        return
    tmp = target.with_name(f".{target.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(data)
        if mode is not None:
            os.chmod(tmp, stat.S_IMODE(mode))
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def _load(path: str, text: bytes, overrides: dict[str, Any] | None = None) -> Any:
    from .pipeline import BadInput, scene_or_bad_input

    try:
        return scene_or_bad_input(path, text, overrides)
    except BadInput as exc:
        raise CliError(str(exc)) from None


def _remote(scene: str, image: str | None = None) -> Any:
    """A context that turns the service's error answers into the words (and exit codes) of local work: the
    scene's problems as ``SCENE:LINE: path: message``, the image's as ``IMAGE: ...``."""
    import contextlib

    from .client import ServerError
    from .pipeline import scene_lines

    @contextlib.contextmanager
    def translating() -> Any:
        try:
            yield
        except ServerError as exc:
            if exc.problems is not None:
                raise CliError("; ".join(scene_lines(scene, exc.body["errors"]))) from None
            if exc.part == "image" and image is not None:
                raise CliError(f"{image}: {exc.detail.removeprefix('image: ')}") from None
            if exc.status in (413, 422):  # a limit of the service's
                raise CliError(f"{scene}: {exc.detail}") from None
            raise CliError(str(exc)) from None

    return translating()


def _cluster(args: argparse.Namespace) -> Any:
    from .cluster import connect

    return connect(args.cluster, wait=args.cluster_wait)


def _budget(args: argparse.Namespace, scene: Any) -> Any:
    """With ``--limits``, ``scene`` checked against the service's limits (exit 2 naming the one it exceeds) and
    the budget its render is held to; without, no limit: a scene on one's own machine is trusted."""
    from tracer.budget import UNLIMITED

    if not args.limits:
        return UNLIMITED
    from .limits import LimitError, budget, check_scene
    from .settings import Settings

    settings = Settings.from_env()
    try:
        check_scene(scene, settings)
    except LimitError as exc:
        raise CliError(f"{args.scene}: {exc}") from None
    return budget(scene, settings)


def _outgrown(args: argparse.Namespace, exc: OverBudget) -> CliError:
    """A render stopped by its ``--limits`` budget, in the service's words (exit 2)."""
    from .limits import outgrown
    from .settings import Settings

    return CliError(f"{args.scene}: {outgrown(exc, Settings.from_env())}")


def cmd_render(args: argparse.Namespace) -> int:
    from tracer import ImageTooLarge, OverBudget, encode_png

    from .cluster import ClusterError
    from .rendering import BandLost, render_pixels

    if args.server and args.cluster:
        raise CliError("--server and --cluster: choose one")
    if args.pass_ is not None or args.light is not None:
        return _render_pass(args)
    _png_name(args.output)
    overrides = {"width": args.width, "height": args.height, "samples": args.samples}
    text = _read(args.scene)
    started = time.perf_counter()
    if args.server:
        from .client import post_json

        with _remote(args.scene):
            data = post_json(args.server, "/render", text, overrides, api_key=args.api_key)
        _write(args.output, data)
        return 0
    scene = _load(args.scene, text, overrides)
    budget = _budget(args, scene)
    bar = ProgressBar()
    try:
        if args.cluster:
            with _cluster(args) as client:
                pixels = render_pixels(scene, client)
        else:
            pixels = render_pixels(scene, threads=args.threads, progress=bar, processes=True, budget=budget)
    except ImageTooLarge as exc:
        raise CliError(f"{args.scene}: {exc}") from None
    except OverBudget as exc:
        raise _outgrown(args, exc) from None
    except BandLost as exc:
        raise CliError(f"{args.scene}: {exc}", code=1) from None
    except ClusterError as exc:
        raise CliError(str(exc)) from None
    finally:
        bar.close()
    _write(args.output, encode_png(pixels))
    if not args.quiet:
        print(f"{args.output}: {pixels.shape[1]}×{pixels.shape[0]} in {time.perf_counter() - started:.3f} s",
              file=sys.stderr)
    return 0


def _render_pass(args: argparse.Namespace) -> int:
    """``render --pass NAME [--light K]``: one pass as a PNG, or its values as ``.npy`` (by the output's name)."""
    from . import passes

    if args.pass_ is None:
        raise CliError("--light: only with --pass (the light whose diffuse, specular or shadow is shown)")
    if args.cluster:
        raise CliError("--pass: renders here or on a --server, not on a cluster")
    fmt: passes.Format = "npy" if args.output.lower().endswith(".npy") else "png"
    if fmt == "png":
        _png_name(args.output)
    overrides = {"width": args.width, "height": args.height, "samples": args.samples}
    text = _read(args.scene)
    started = time.perf_counter()
    if args.server:
        from .client import post_json

        query = {**overrides, "pass": args.pass_, "light": args.light, "format": fmt}
        with _remote(args.scene):
            data = post_json(args.server, "/render", text, query, api_key=args.api_key)
    else:
        from tracer import OverBudget

        scene = _load(args.scene, text, overrides)
        try:
            data = passes.encoded(args.pass_, passes.values(scene, args.pass_, args.light, args.threads,
                                                            budget=_budget(args, scene)), fmt)
        except ValueError as exc:
            raise CliError(f"{args.scene}: {exc}") from None
        except OverBudget as exc:
            raise _outgrown(args, exc) from None
    _write(args.output, data)
    if not args.quiet:
        of = "" if args.pass_ not in passes.OF_A_LIGHT else " of every light" if args.light is None else \
            f" of light {args.light}"
        print(f"{args.output}: the {args.pass_} pass{of} ({'values' if fmt == 'npy' else 'PNG'}) in "
              f"{time.perf_counter() - started:.3f} s", file=sys.stderr)
    return 0


def cmd_validate(args: argparse.Namespace) -> int:
    from schemas import SceneError

    from .pipeline import load_scene, scene_lines

    text = _read(args.scene)
    if args.server:
        from .client import ServerError, post_json

        try:
            post_json(args.server, "/validate", text, api_key=args.api_key)
        except ServerError as exc:
            if exc.problems is None:
                with _remote(args.scene):
                    raise
            lines = scene_lines(args.scene, exc.body["errors"])
        else:
            lines = []
    else:
        try:
            _warn_of_limits(args.scene, load_scene(args.scene, text))
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
    from .limits import beyond_limits
    from .settings import Settings

    for warning in beyond_limits(scene, Settings.from_env()):
        print(f"{name}: warning: {warning}", file=sys.stderr)


def _thresholds(args: argparse.Namespace) -> None:
    """The grading thresholds, checked as HTTP checks them (and in the same words)."""
    for name, value, high in (("tolerance", args.tolerance, 255), ("max_fraction", args.max_fraction, 1)):
        if not 0 <= value <= high:
            raise CliError(f"{name}: must be between 0 and {high:g}")


def _png_name(path: str | None) -> None:
    if path is not None and path != "-" and not path.lower().endswith(".png"):
        raise CliError(f"{path}: phongray writes PNG images; name the output *.png (or - for standard output)")


def _verdict(args: argparse.Namespace, result: dict[str, Any]) -> int:
    """Print a grade (in words, or as JSON with ``--json``); exit 0 for a pass, 1 for a fail."""
    if args.json:
        print(json.dumps(result, indent=1, ensure_ascii=False))
    else:
        print("\n".join(describe(result)))
    return 0 if result["passed"] else 1


def cmd_grade(args: argparse.Namespace) -> int:
    """Exit 0 when the submission passes, 1 when it fails, 2 for bad input."""
    from . import grading, pipeline

    _thresholds(args)
    _png_name(args.heatmap)
    kind: Kind = "raw" if args.raw_heatmap else "verdict"
    heat: bytes | None = None
    text, image = _read(args.scene), _read_image(args.image)
    if args.server:
        from .client import post_form

        fields: dict[str, bytes | str] = {"scene": text, "tolerance": repr(args.tolerance),
                                          "max_fraction": repr(args.max_fraction),
                                          "diagnose": "false" if args.no_diagnosis else "true"}
        files = {"image": ("submission.png", image, "image/png")}
        with _remote(args.scene, args.image):
            result = json.loads(post_form(args.server, "/grade", fields, files, api_key=args.api_key))
            if args.heatmap:
                heat = post_form(args.server, "/grade", fields, files, {"format": "png", "heatmap": kind},
                                 api_key=args.api_key)
    else:
        from tracer import ImageTooLarge, OverBudget, encode_png

        from .rendering import render_pixels

        scene = _load(args.scene, text)
        try:
            reference = encode_png(render_pixels(scene, budget=_budget(args, scene)))
        except ImageTooLarge as exc:
            raise CliError(f"{args.scene}: {exc}") from None
        except OverBudget as exc:
            raise _outgrown(args, exc) from None
        try:
            graded = pipeline.grade_png(reference, image, args.tolerance, args.max_fraction,
                                        kind if args.heatmap else None, legend=True, scene=lambda: scene,
                                        checks=pipeline.Checks(diagnose=not args.no_diagnosis))
        except grading.ImageError as exc:
            raise CliError(f"{args.image}: {exc}") from None
        result, heat = graded.as_dict(), graded.heatmap
    if args.heatmap and heat is not None:
        _write(args.heatmap, heat)
    return _verdict(args, result)


def cmd_compare(args: argparse.Namespace) -> int:
    """Two images graded without a scene: exit 0 pass, 1 fail, 2 bad input."""
    from . import grading, pipeline

    _thresholds(args)
    _png_name(args.heatmap)
    reference, image = _read_image(args.reference), _read_image(args.image)
    try:
        pixels = pipeline.read_reference(reference)
    except grading.ImageError as exc:
        raise CliError(f"{args.reference}: {exc}") from None
    try:
        submitted = pipeline.read_image(image, (pixels.shape[1], pixels.shape[0]))
    except grading.ImageError as exc:
        raise CliError(f"{args.image}: {str(exc).replace('the scene is', 'the reference is')}") from None
    graded = pipeline.compare(reference, submitted, args.tolerance, args.max_fraction,
                              ("raw" if args.raw_heatmap else "verdict") if args.heatmap else None, legend=True,
                              reference=pixels)
    if args.heatmap and graded.heatmap is not None:
        _write(args.heatmap, graded.heatmap)
    return _verdict(args, graded.as_dict())


def cmd_grade_class(args: argparse.Namespace) -> int:
    """Exit 0 when the batch ran (whatever the verdicts), 2 when the TA's input or set-up is unusable."""
    from .classgrade import ClassRun, grade_class
    from .classgrade.errors import ClassError
    from .cluster import ClusterError

    _thresholds(args)
    if args.server and args.cluster:
        raise CliError("--server and --cluster: choose one")
    bar = ProgressBar(unit="pairs")
    bar.enabled = bar.enabled and not args.quiet
    try:
        run = ClassRun(Path(args.scenes), Path(args.submissions), Path(args.output), args.tolerance,
                       args.max_fraction, jobs=args.jobs, server=args.server, cluster=args.cluster,
                       api_key=args.api_key,
                       student_scenes=Path(args.student_scenes) if args.student_scenes else None,
                       tasks_file=Path(args.tasks) if args.tasks else None, cluster_wait=args.cluster_wait,
                       diagnose=not args.no_diagnosis,
                       limits=args.limits)
        outcome = grade_class(run, progress=bar)
    except (ClassError, ClusterError) as exc:  # (names in it are printed with their control characters escaped)
        raise CliError(printable(str(exc))) from None
    except OSError as exc:
        raise CliError(printable(f"{exc.filename or args.output}: {exc.strerror or exc}")) from None
    finally:
        bar.close()
    for name, why in outcome.ignored:
        print(printable(f"ignored: {name}: {why}"), file=sys.stderr)
    if not args.quiet:
        print(printable(f"{outcome.summary()}; report in {Path(args.output) / 'index.html'}"))
    return 0


def cmd_autograder(args: argparse.Namespace) -> int:
    """Exit 0 when the bundle is written, 2 when the TA's input is unusable (nothing is written then)."""
    from .classgrade.autograder import build
    from .classgrade.errors import ClassError

    if not args.output.endswith(".zip"):
        raise CliError(f"{args.output}: Gradescope takes the autograder as a zip; name the output *.zip")
    try:
        built = build(Path(args.scenes), Path(args.output), Path(args.tasks) if args.tasks else None,
                      Path(args.student_scenes) if args.student_scenes else None)
    except ClassError as exc:
        raise CliError(printable(str(exc))) from None
    print(printable(f"{args.output}: {counted(len(built.tasks), 'task')} ({', '.join(built.tasks)}), "
                    f"{counted(built.references, 'reference')} rendered, {built.size / 1e6:.1f} MB; upload it as "
                    "the assignment's autograder"))
    return 0


def cmd_serve(args: argparse.Namespace) -> int:
    import socket

    from .settings import Settings

    Settings.from_env()  # a PHONGRAY_* setting of the wrong type is told as itself, before the port is taken
    try:  # a port that cannot be had is one line here, not uvicorn's traceback in a worker
        with socket.create_server((args.host, args.port)):
            pass
    except OSError as exc:
        raise CliError(f"cannot listen on {args.host}:{args.port}: {exc.strerror or exc}") from None
    from .server import serve

    serve(args.host, args.port, args.workers)
    return 0


def cmd_schema(args: argparse.Namespace) -> int:
    from schemas import json_schema

    print(json.dumps(json_schema(), indent=2))
    return 0


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < 1:
        raise argparse.ArgumentTypeError("must be ≥ 1")
    return value


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("phongray")
    except PackageNotFoundError:  # run from a source tree that was never installed
        return "unknown (not installed)"


class _Version(argparse.Action):
    """``--version``, looked up only when asked for (reading package metadata costs every command 30 ms)."""

    def __init__(self, option_strings: Sequence[str], dest: str = argparse.SUPPRESS, help: str | None = None):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, help=help)

    def __call__(self, parser: argparse.ArgumentParser, namespace: Any, values: Any, option: str | None = None) -> None:
        print(f"phongray {_version()}")
        parser.exit()


class _Help(argparse.HelpFormatter):
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


def _index(text: str) -> int:
    return _integer(text, 0, None, "an index (0, 1, ...)")


def _port(text: str) -> int:
    return _integer(text, 0, 65535, "a TCP port (0–65535)")


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not value >= 0:
        raise argparse.ArgumentTypeError("must be ≥ 0")
    return value


def build_parser() -> argparse.ArgumentParser:
    formatter = _Help
    parser = argparse.ArgumentParser(prog="phongray", description="A reference Phong/Whitted ray tracer.",
                                     formatter_class=formatter)
    parser.add_argument("-V", "--version", action=_Version, help="show the version and exit")
    sub = parser.add_subparsers(dest="command", required=True)

    def command(name: str, help: str, **kw: Any) -> argparse.ArgumentParser:
        return sub.add_parser(name, help=help, description=kw.pop("description", help[0].upper() + help[1:] + "."),
                              formatter_class=formatter, **kw)

    def remote(p: argparse.ArgumentParser, cluster: bool = False) -> None:
        p.add_argument("--server", metavar="URL", help="send the work to a running phongray service "
                                                       "(http:// is assumed when the URL has no scheme)")
        p.add_argument("--api-key", metavar="KEY", default=None,
                       help="the service's API key, for --server (default: $PHONGRAY_API_KEY)")
        if cluster:
            p.add_argument("--cluster", metavar="tcp://HOST:PORT",
                           help="run the work on this Dask scheduler's cluster (default: $PHONGRAY_CLUSTER; "
                                "needs 'phongray[cluster]')")
            p.add_argument("--cluster-wait", metavar="SECONDS", type=_seconds,
                           help="how long to wait for the cluster's first worker before giving up "
                                "(default: $PHONGRAY_CLUSTER_WAIT, else 30)")

    def limits(p: argparse.ArgumentParser) -> None:
        p.add_argument("--limits", action="store_true",
                       help="hold the scene to the service's limits (PHONGRAY_* settings: pixels, samples, depth, "
                            "the cost counted as it renders, render_timeout for grade-class), as a server would; "
                            "without it a scene here is trusted")

    def thresholds(p: argparse.ArgumentParser) -> None:
        p.add_argument("--tolerance", type=float, default=2.0, help="8-bit levels a pixel may differ by (0–255)")
        p.add_argument("--max-fraction", type=float, default=0.001,
                       help="fraction of pixels that may be off even against their 3×3 neighbourhood (0–1)")

    def no_diagnosis(p: argparse.ArgumentParser, what: str = "") -> None:
        p.add_argument("--no-diagnosis", action="store_true",
                       help=what or "skip naming the likely mistake of a failing image (it renders the scene once "
                                    "per classic mistake)")

    def verdict(p: argparse.ArgumentParser) -> None:
        thresholds(p)
        p.add_argument("--heatmap", metavar="OUT.png", help="write the heat-map here: the pixels that decided the "
                                                            "verdict, brighter and darker, with a legend")
        p.add_argument("--raw-heatmap", action="store_true", help="draw the plain difference in the heat-map instead")
        p.add_argument("--json", action="store_true", help="print the grade as JSON (the numbers of /grade)")

    p = command("render", "render a scene to a PNG")
    p.add_argument("scene", help="scene JSON file ('-' for stdin)")
    p.add_argument("-o", "--output", required=True, help="output PNG, *.png ('-' for stdout); with --pass, "
                                                          "*.npy writes the pass's values as a NumPy array")
    p.add_argument("--width", type=_positive_int, help="image width in pixels (default: the scene's)")
    p.add_argument("--height", type=_positive_int, help="image height in pixels (default: the scene's)")
    p.add_argument("--samples", type=_positive_int, help="n: an n×n grid of sub-samples per pixel "
                                                         "(default: the scene's)")
    p.add_argument("--threads", type=_positive_int, help="worker threads (default: all cores)")
    p.add_argument("--pass", dest="pass_", metavar="NAME", choices=PASS_NAMES,
                   help="render one pass instead: " + ", ".join(PASS_NAMES) + " (the first six are the image's "
                        "additive terms)")
    p.add_argument("--light", type=_index, metavar="K", help="with --pass: light K alone (its index in lights)")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    limits(p)
    remote(p, cluster=True)
    p.set_defaults(func=cmd_render)

    p = command("validate", "check a scene; print every error with its place and line")
    p.add_argument("scene", help="scene JSON file ('-' for stdin)")
    remote(p)
    p.set_defaults(func=cmd_validate)

    p = command("grade", "grade a submitted PNG against the scene's reference render",
                description="Grade a submitted PNG against the scene's reference render. Exit 0 pass, 1 fail, "
                            "2 bad input.")
    p.add_argument("scene", help="scene JSON file")
    p.add_argument("image", help="the submitted PNG")
    verdict(p)
    no_diagnosis(p)
    limits(p)
    remote(p)
    p.set_defaults(func=cmd_grade)

    p = command("compare", "grade one PNG against another, without a scene",
                description="Grade IMAGE against REFERENCE (two PNGs of one size) as 'grade' would against a "
                            "render. Exit 0 pass, 1 fail, 2 bad input.")
    p.add_argument("reference", help="the reference PNG")
    p.add_argument("image", help="the PNG to grade")
    verdict(p)
    no_diagnosis(p, "accepted as grade accepts it: without a scene, compare never names a likely mistake")
    p.set_defaults(func=cmd_compare)

    p = command("grade-class", "grade every student's images of every task; write a report",
                description="SCENES/<task>.json are the tasks, SUBMISSIONS/<student>/<task>.png the images (any "
                            "case of the name, a resubmission's -1 or (1), or one folder deeper; Moodle's "
                            "<name>_<id>_assignsubmission_file_ folders and Canvas's flat <login>_<id>_<id>_<task>.png "
                            "too). A student's own scene comes from the TA's --student-scenes "
                            "DIR/<student>/<task>.json, never from the submissions. Writes report.json, report.csv, "
                            "gradebook.csv, index.html, gradescope/<student>/results.json, references and heat-maps "
                            "into REPORT. Exit 0 when the batch ran, 2 when the TA's input or set-up is unusable "
                            "(nothing is graded then).")
    p.add_argument("scenes", metavar="SCENES_DIR", help="a <task>.json per task")
    p.add_argument("submissions", metavar="SUBMISSIONS_DIR", help="the students' images, as an LMS downloads them")
    p.add_argument("-o", "--output", metavar="REPORT_DIR", required=True, help="where the report goes")
    p.add_argument("--student-scenes", metavar="DIR", help="the TA's folder of students' own scenes, "
                                                           "<student>/<task>.json")
    p.add_argument("--tasks", metavar="TASKS.json", help='per task its points, thresholds and deductions by '
                                                         'mistake id: {"spheres": {"points": 10, "tolerance": 3, '
                                                         '"deductions": {"no-shadows": 4}}}')
    thresholds(p)
    p.add_argument("--jobs", type=_positive_int, help="processes (default: all cores; with --server, 4 requests)")
    no_diagnosis(p, "skip naming the likely mistake of each failing image (it renders the scene once per "
                    "classic mistake): a faster run, with an empty 'likely' column")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors and ignored files (no "
                                                              "progress bar, no summary line)")
    limits(p)
    remote(p, cluster=True)
    p.set_defaults(func=cmd_grade_class)

    p = command("autograder", "write a Gradescope autograder (setup.sh, run_autograder) for a course's scenes",
                description="SCENES/<task>.json are the tasks. Writes a zip to upload to Gradescope as a "
                            "programming assignment's autograder: it installs phongray (setup.sh) and grades the "
                            "PNG images a student uploads, one per task, with a test per task (run_autograder). "
                            "The references are rendered now. Exit 0 when written, 2 when the TA's input is "
                            "unusable.")
    p.add_argument("scenes", metavar="SCENES_DIR", help="a <task>.json per task")
    p.add_argument("-o", "--output", metavar="AUTOGRADER.zip", required=True, help="the zip to write")
    p.add_argument("--tasks", metavar="TASKS.json", help="per task its points, thresholds and accepted variants")
    p.add_argument("--student-scenes", metavar="DIR", help="students' own scenes, <student>/<task>.json, "
                                                           "<student> being their Gradescope email, its part "
                                                           "before the @, student id or name")
    p.set_defaults(func=cmd_autograder)

    p = command("serve", "run the HTTP service (settings from PHONGRAY_* variables, see docs/service.md)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on")
    p.add_argument("--port", type=_port, default=8000, help="port to listen on")
    p.add_argument("--workers", type=_positive_int, default=1, help="worker processes")
    p.set_defaults(func=cmd_serve)

    sub.add_parser("bench", help="run the benchmark (speed, memory, class grading, cluster, HTTP, speed against "
                                 "error); 'phongray bench --help' for its options")

    p = command("schema", "print the scene JSON Schema")
    p.set_defaults(func=cmd_schema)
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
            from .cluster import CLUSTER_WAIT  # no PHONGRAY_* variable: the settings are their defaults, and
            # a render's start-up need not import pydantic-settings to learn them
            if args.cluster_wait is None:
                args.cluster_wait = CLUSTER_WAIT
            return args
        from .settings import Settings

        settings = Settings.from_env()
        if args.cluster is None:
            args.cluster = settings.cluster or None
        if args.cluster_wait is None:
            args.cluster_wait = settings.cluster_wait
    return args


def _quiet_dask() -> None:
    """Dask's own log lines (a lost scheduler's reconnection tracebacks) off the terminal: phongray says what
    happened to the cluster in one line of its own."""
    import logging

    try:
        import distributed  # noqa: F401  (its import sets its loggers' levels: set them after it)
    except ImportError:
        return
    for name in ["distributed", *(n for n in logging.Logger.manager.loggerDict if n.startswith("distributed."))]:
        logging.getLogger(name).setLevel(logging.CRITICAL)


def _settings_error(exc: ValueError) -> int:
    """A PHONGRAY_* variable of the wrong type is one line and exit 2 (any other ValueError is a bug: raised)."""
    from .settings import SettingsError

    if not isinstance(exc, SettingsError):
        raise exc
    print(f"phongray: {exc}", file=sys.stderr)
    return EXIT_BAD_INPUT


def main(argv: Sequence[str] | None = None) -> int:
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
        if ProgressBar.active is not None:
            ProgressBar.active.close()  # the message goes on a line of its own
        print("phongray: interrupted", file=sys.stderr)
        return 130
    except MemoryError:
        print("phongray: out of memory", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
