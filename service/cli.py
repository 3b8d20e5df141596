"""The ``phongray`` command: render, validate, schema (and more as they land).

Every failure a user can cause ends in a one-line message on stderr and a
non-zero exit, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any, Sequence

EXIT_BAD_INPUT = 2


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


def _load(path: str, overrides: dict[str, Any] | None = None):  # type: ignore[no-untyped-def]
    from schemas import SceneError, parse_json, validate_scene

    text = _read(path)
    try:
        data = parse_json(text, shared=False)
        if overrides and isinstance(data, dict) and isinstance(data.get("image"), dict):
            data["image"].update({k: v for k, v in overrides.items() if v is not None})
        return validate_scene(data)
    except SceneError as exc:
        raise CliError("; ".join(_lines(path, exc, text))) from None


def _lines(name: str, exc: Any, text: bytes) -> list[str]:
    """``FILE:LINE: path: message`` per problem (the line of the JSON text, as HTTP gives it, where known)."""
    from schemas.locate import as_lines

    return as_lines(name, exc.problems, text)


def _clock(seconds: float) -> str:
    seconds = int(seconds)
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}" if seconds >= 3600 else \
        f"{seconds // 60}:{seconds % 60:02d}"


class ProgressBar:
    """A one-line progress bar on stderr, shown only on a terminal and only after a second."""

    def __init__(self, delay: float = 1.0, unit: str | None = None):
        self.start = time.monotonic()
        self.delay = delay
        self.unit = unit  # when set, the line shows "done/total unit" and an ETA
        self.shown = False
        self.enabled = sys.stderr.isatty()
        self.first: tuple[float, int] | None = None

    def __call__(self, done: int, total: int) -> None:
        now = time.monotonic()
        if self.first is None:
            self.first = (now, done)
        if not self.enabled or now - self.start < self.delay:
            return
        self.shown = True
        width = 30
        filled = int(width * done / max(total, 1))
        line = f"\r[{'#' * filled}{'.' * (width - filled)}] {100 * done / max(total, 1):5.1f}%"
        if self.unit:
            line += f" {done}/{total} {self.unit}"
        t0, d0 = self.first
        rate = (done - d0) / max(now - t0, 1e-9)
        eta = _clock((total - done) / rate) if rate > 0 else "?"
        line += f", {_clock(now - self.start)} elapsed, ETA {eta}  "
        ProgressBar.active = self
        sys.stderr.write(line)
        sys.stderr.flush()

    #: the bar on screen, so that an interruption can finish its line first
    active: "ProgressBar | None" = None

    def close(self) -> None:
        if self.shown and ProgressBar.active is self:
            sys.stderr.write("\n")
        ProgressBar.active = None


def _server_call(func, *a, **kw):  # type: ignore[no-untyped-def]
    from .client import ServerError

    try:
        return func(*a, **kw)
    except ServerError as exc:
        if exc.problems is not None:
            raise CliError(exc.problems, 1 if exc.status == 422 else EXIT_BAD_INPUT) from None
        raise CliError(str(exc)) from None


def cmd_render(args: argparse.Namespace) -> int:
    from tracer import ImageTooLarge, encode_png, render

    _png_name(args.output)
    overrides = {"width": args.width, "height": args.height, "samples": args.samples}
    if args.server:
        from .client import post_json

        data = _server_call(post_json, args.server, "/render", _read(args.scene), overrides, api_key=args.api_key)
        _write(args.output, data)
        return 0
    scene = _load(args.scene, overrides)
    bar = ProgressBar()
    started = time.perf_counter()
    try:
        if args.cluster:
            from .cluster import ClusterError, connect
            from .cluster import render as render_on

            try:
                with connect(args.cluster) as client:
                    pixels = render_on(client, scene.model_dump_json().encode(), scene.image.width,
                                       scene.image.height)
            except ClusterError as exc:
                raise CliError(str(exc)) from None
        else:
            pixels = render(scene, threads=args.threads, progress=bar)
    except ImageTooLarge as exc:
        raise CliError(f"{args.scene}: {exc}") from None
    bar.close()
    data = encode_png(pixels)
    _write(args.output, data)
    if not args.quiet:
        print(f"{args.output}: {pixels.shape[1]}×{pixels.shape[0]} in {time.perf_counter() - started:.3f} s",
              file=sys.stderr)
    return 0


def _write(path: str, data: bytes) -> None:
    try:
        if path == "-":
            sys.stdout.buffer.write(data)
        else:
            Path(path).write_bytes(data)
    except OSError as exc:
        raise CliError(f"{path}: cannot write: {exc.strerror or exc}") from None


def cmd_validate(args: argparse.Namespace) -> int:
    from schemas import SceneError, load_scene

    if args.server:
        from .client import ServerError, post_json

        try:
            post_json(args.server, "/validate", _read(args.scene), api_key=args.api_key)
        except ServerError as exc:
            if exc.status != 422 or not isinstance(exc.body, dict):
                raise CliError(str(exc)) from None
            for e in exc.body.get("errors", []):
                where = f"{args.scene}:{e['line']}" if e.get("line") else args.scene
                print(f"{where}: {e['path']}: {e['message']}" if e.get("path") else f"{where}: {e['message']}")
            return 1
        print(f"{args.scene}: valid")
        return 0

    text = _read(args.scene)
    try:
        load_scene(text)
    except SceneError as exc:
        for line in _lines(args.scene, exc, text):
            print(line)
        return 1
    print(f"{args.scene}: valid")
    return 0


def _thresholds(args: argparse.Namespace) -> None:
    """The grading thresholds, checked as HTTP checks them (and in the same words)."""
    for name, value, high in (("tolerance", args.tolerance, 255), ("max_fraction", args.max_fraction, 1)):
        if not 0 <= value <= high:
            raise CliError(f"{name}: must be between 0 and {high:g}")


def _png_name(path: str | None) -> None:
    if path is not None and path != "-" and not path.lower().endswith(".png"):
        raise CliError(f"{path}: phongray writes PNG images; name the output *.png (or - for standard output)")


def cmd_grade(args: argparse.Namespace) -> int:
    """Exit 0 when the submission passes, 1 when it fails, 2 for bad input."""
    _thresholds(args)
    _png_name(args.heatmap)
    image = _read(args.image)
    if args.server:
        from .client import post_form

        fields = {"scene": _read(args.scene), "tolerance": str(args.tolerance), "max_fraction": str(args.max_fraction)}
        files = {"image": ("submission.png", image, "image/png")}
        result = json.loads(_server_call(post_form, args.server, "/grade", fields, files, api_key=args.api_key))
        if args.heatmap:
            _write(args.heatmap, _server_call(post_form, args.server, "/grade", fields, files, {"format": "png"},
                                              api_key=args.api_key))
    else:
        import hashlib

        from tracer import ImageTooLarge, encode_png, render

        from . import grading

        scene = _load(args.scene)
        try:
            reference = render(scene)
        except ImageTooLarge as exc:
            raise CliError(f"{args.scene}: {exc}") from None
        try:
            submitted = grading.read_submission(image, (reference.shape[1], reference.shape[0]))
        except grading.ImageError as exc:
            raise CliError(f"{args.image}: {exc}") from None
        sha = hashlib.sha256(encode_png(reference)).hexdigest()
        result = grading.grade(reference, submitted, sha, args.tolerance, args.max_fraction).as_dict()
        if args.heatmap:
            _write(args.heatmap, grading.heatmap(reference, submitted))
    print("PASS" if result["passed"] else "FAIL")
    for key, value in result.items():
        if key != "passed":
            print(f"  {key}: {value}")
    return 0 if result["passed"] else 1


def cmd_grade_class(args: argparse.Namespace) -> int:
    """Exit 0 when the batch ran (whatever the verdicts), 2 when its input is unusable."""
    from .classgrade import ClassError, grade_class

    _thresholds(args)
    from .cluster import ClusterError

    if args.server and args.cluster:
        raise CliError("--server and --cluster: choose one")
    bar = ProgressBar(unit="pairs")
    try:
        outcome = grade_class(Path(args.scenes), Path(args.submissions), Path(args.output), args.tolerance,
                              args.max_fraction, jobs=args.jobs, server=args.server, cluster=args.cluster,
                              progress=bar, api_key=args.api_key)
    except (ClassError, ClusterError) as exc:
        raise CliError(str(exc)) from None
    except OSError as exc:
        raise CliError(f"{exc.filename or args.output}: {exc.strerror or exc}") from None
    finally:
        bar.close()
    for name in outcome.ignored:
        print(f"ignored: {name}", file=sys.stderr)
    print(f"{outcome.summary()}; report in {Path(args.output) / 'index.html'}")
    return 0


def cmd_serve(args: argparse.Namespace) -> int:
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
            p.add_argument("--cluster", metavar="tcp://HOST:PORT", default=os.environ.get("PHONGRAY_CLUSTER") or None,
                           help="run the work on this Dask scheduler's cluster (default: $PHONGRAY_CLUSTER; "
                                "needs 'phongray[cluster]')")

    def thresholds(p: argparse.ArgumentParser) -> None:
        p.add_argument("--tolerance", type=float, default=2.0, help="8-bit levels a pixel may differ by (0–255)")
        p.add_argument("--max-fraction", type=float, default=0.001,
                       help="fraction of pixels that may be off even against their 3×3 neighbourhood (0–1)")

    p = command("render", "render a scene to a PNG")
    p.add_argument("scene", help="scene JSON file ('-' for stdin)")
    p.add_argument("-o", "--output", required=True, help="output PNG, *.png ('-' for stdout)")
    p.add_argument("--width", type=_positive_int, help="image width in pixels (default: the scene's)")
    p.add_argument("--height", type=_positive_int, help="image height in pixels (default: the scene's)")
    p.add_argument("--samples", type=_positive_int, help="n: an n×n grid of sub-samples per pixel "
                                                         "(default: the scene's)")
    p.add_argument("--threads", type=_positive_int, help="worker threads (default: all cores)")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    remote(p, cluster=True)
    p.set_defaults(func=cmd_render)

    p = command("validate", "check a scene; print every error with its place and line")
    p.add_argument("scene", help="scene JSON file ('-' for stdin)")
    remote(p)
    p.set_defaults(func=cmd_validate)

    p = command("grade", "grade a submitted PNG against the scene's reference render")
    p.add_argument("scene", help="scene JSON file")
    p.add_argument("image", help="the submitted PNG")
    thresholds(p)
    p.add_argument("--heatmap", metavar="OUT.png", help="write the difference heat-map here")
    remote(p)
    p.set_defaults(func=cmd_grade)

    p = command("grade-class", "grade every student's images of every task; write a report",
                description="SCENES/<task>.json are the tasks, SUBMISSIONS/<student>/<task>.png the images "
                            "(a SUBMISSIONS/<student>/<task>.json is that student's own scene). Writes "
                            "report.json, report.csv, index.html, references and heat-maps into REPORT.")
    p.add_argument("scenes", metavar="SCENES_DIR", help="a <task>.json per task")
    p.add_argument("submissions", metavar="SUBMISSIONS_DIR", help="a folder per student")
    p.add_argument("-o", "--output", metavar="REPORT_DIR", required=True, help="where the report goes")
    thresholds(p)
    p.add_argument("--jobs", type=_positive_int, help="processes (default: all cores; with --server, 4 requests)")
    remote(p, cluster=True)
    p.set_defaults(func=cmd_grade_class)

    p = command("serve", "run the HTTP service (settings from PHONGRAY_* variables, see the README)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on")
    p.add_argument("--port", type=int, default=8000, help="port to listen on")
    p.add_argument("--workers", type=_positive_int, default=1, help="worker processes")
    p.set_defaults(func=cmd_serve)

    sub.add_parser("bench", help="run the benchmark (speed, memory, class grading, cluster, HTTP, speed against "
                                 "error); 'phongray bench --help' for its options")

    p = command("schema", "print the scene JSON Schema")
    p.set_defaults(func=cmd_schema)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["bench"]:  # the benchmark has its own options
        from bench.run import main as bench_main

        return bench_main(argv[1:])
    parser = build_parser()
    args = parser.parse_args(argv)
    for stream in (sys.stdout, sys.stderr):  # a scene's text may not be valid Unicode (a lone surrogate)
        if hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="backslashreplace")
    try:
        return int(args.func(args))
    except CliError as exc:
        print(f"phongray: {exc}", file=sys.stderr)
        return exc.code
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
