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

    try:
        data = parse_json(_read(path))
        if overrides and isinstance(data, dict) and isinstance(data.get("image"), dict):
            data["image"].update({k: v for k, v in overrides.items() if v is not None})
        return validate_scene(data)
    except SceneError as exc:
        raise CliError(f"{path}: " + "; ".join(_lines(exc))) from None


def _lines(exc: Any) -> list[str]:
    from schemas import format_problem

    return [format_problem(p) for p in exc.problems]


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
            t0, d0 = self.first
            rate = (done - d0) / max(now - t0, 1e-9)
            eta = f"{int((total - done) / rate) // 60}:{int((total - done) / rate) % 60:02d}" if rate > 0 else "?"
            line += f" {done}/{total} {self.unit}, ETA {eta}  "
        sys.stderr.write(line)
        sys.stderr.flush()

    def close(self) -> None:
        if self.shown:
            sys.stderr.write("\n")


def _server_call(func, *a, **kw):  # type: ignore[no-untyped-def]
    from .client import ServerError

    try:
        return func(*a, **kw)
    except ServerError as exc:
        body = exc.body
        if isinstance(body, dict) and body.get("errors"):
            lines = [f"{e['path']}: {e['message']}" if e.get("path") else e["message"] for e in body["errors"]]
            raise CliError("; ".join(lines), 1 if exc.status == 422 else EXIT_BAD_INPUT) from None
        raise CliError(str(exc)) from None


def cmd_render(args: argparse.Namespace) -> int:
    from tracer import ImageTooLarge, encode_png, render

    overrides = {"width": args.width, "height": args.height, "samples": args.samples}
    if args.server:
        from .client import post_json

        data = _server_call(post_json, args.server, "/render", _read(args.scene), overrides)
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
            post_json(args.server, "/validate", _read(args.scene))
        except ServerError as exc:
            if exc.status != 422 or not isinstance(exc.body, dict):
                raise CliError(str(exc)) from None
            for e in exc.body.get("errors", []):
                print(f"{args.scene}: {e['path']}: {e['message']}" if e.get("path") else f"{args.scene}: {e['message']}")
            return 1
        print(f"{args.scene}: valid")
        return 0

    try:
        load_scene(_read(args.scene))
    except SceneError as exc:
        for line in _lines(exc):
            print(f"{args.scene}: {line}")
        return 1
    print(f"{args.scene}: valid")
    return 0


def cmd_grade(args: argparse.Namespace) -> int:
    """Exit 0 when the submission passes, 1 when it fails, 2 for bad input."""
    image = _read(args.image)
    if args.server:
        from .client import post_form

        fields = {"scene": _read(args.scene), "tolerance": str(args.tolerance), "max_fraction": str(args.max_fraction)}
        files = {"image": ("submission.png", image, "image/png")}
        result = json.loads(_server_call(post_form, args.server, "/grade", fields, files))
        if args.heatmap:
            _write(args.heatmap, _server_call(post_form, args.server, "/grade", fields, files, {"format": "png"}))
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

    if not 0 <= args.tolerance <= 255 or not 0 <= args.max_fraction <= 1:
        raise CliError("--tolerance must be in 0..255 and --max-fraction in 0..1")
    from .cluster import ClusterError

    if args.server and args.cluster:
        raise CliError("--server and --cluster: choose one")
    bar = ProgressBar(unit="pairs")
    try:
        outcome = grade_class(Path(args.scenes), Path(args.submissions), Path(args.output), args.tolerance,
                              args.max_fraction, jobs=args.jobs, server=args.server, cluster=args.cluster,
                              progress=bar)
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


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="phongray", description="A reference Phong/Whitted ray tracer.")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("render", help="render a scene to a PNG")
    p.add_argument("scene", help="scene JSON file ('-' for stdin)")
    p.add_argument("-o", "--output", required=True, help="output PNG ('-' for stdout)")
    p.add_argument("--width", type=_positive_int)
    p.add_argument("--height", type=_positive_int)
    p.add_argument("--samples", type=_positive_int, help="n: an n×n grid of sub-samples per pixel")
    p.add_argument("--threads", type=_positive_int, help="worker threads (default: all cores)")
    p.add_argument("-q", "--quiet", action="store_true")
    p.add_argument("--server", metavar="URL", help="send the work to a running phongray service")
    p.add_argument("--cluster", metavar="tcp://HOST:PORT", default=os.environ.get("PHONGRAY_CLUSTER") or None,
                   help="run the work on this Dask scheduler's cluster (default: $PHONGRAY_CLUSTER; "
                        "needs 'phongray[cluster]')")
    p.set_defaults(func=cmd_render)

    p = sub.add_parser("validate", help="check a scene; print every error with its place")
    p.add_argument("scene")
    p.add_argument("--server", metavar="URL", help="send the work to a running phongray service")
    p.set_defaults(func=cmd_validate)

    p = sub.add_parser("grade", help="grade a submitted PNG against the scene's reference render")
    p.add_argument("scene")
    p.add_argument("image", help="the submitted PNG")
    p.add_argument("--tolerance", type=float, default=2.0, help="8-bit levels a pixel may differ by (default 2)")
    p.add_argument("--max-fraction", type=float, default=0.001,
                   help="fraction of pixels that may be off even against their 3×3 neighbourhood (default 0.001)")
    p.add_argument("--heatmap", metavar="OUT.png", help="write the difference heat-map")
    p.add_argument("--server", metavar="URL", help="send the work to a running phongray service")
    p.set_defaults(func=cmd_grade)

    p = sub.add_parser("grade-class", help="grade every student's images of every task; write a report",
                       description="SCENES/<task>.json are the tasks, SUBMISSIONS/<student>/<task>.png the images "
                                   "(a SUBMISSIONS/<student>/<task>.json is that student's own scene). Writes "
                                   "report.json, report.csv, index.html, references and heat-maps into REPORT.")
    p.add_argument("scenes", metavar="SCENES_DIR")
    p.add_argument("submissions", metavar="SUBMISSIONS_DIR")
    p.add_argument("-o", "--output", metavar="REPORT_DIR", required=True, help="where the report goes")
    p.add_argument("--tolerance", type=float, default=2.0, help="8-bit levels a pixel may differ by (default 2)")
    p.add_argument("--max-fraction", type=float, default=0.001,
                   help="fraction of pixels that may be off even against their 3×3 neighbourhood (default 0.001)")
    p.add_argument("--jobs", type=_positive_int, help="processes (default: all cores; with --server, 4 requests)")
    p.add_argument("--server", metavar="URL", help="send the work to a running phongray service")
    p.add_argument("--cluster", metavar="tcp://HOST:PORT", default=os.environ.get("PHONGRAY_CLUSTER") or None,
                   help="run the work on this Dask scheduler's cluster (default: $PHONGRAY_CLUSTER; "
                        "needs 'phongray[cluster]')")
    p.set_defaults(func=cmd_grade_class)

    p = sub.add_parser("serve", help="run the HTTP service")
    p.add_argument("--host", default="127.0.0.1")
    p.add_argument("--port", type=int, default=8000)
    p.add_argument("--workers", type=_positive_int, default=1)
    p.set_defaults(func=cmd_serve)

    sub.add_parser("bench", help="run the benchmark (speed, memory, HTTP, speed against error); "
                                 "'phongray bench --help' for its options")

    p = sub.add_parser("schema", help="print the scene JSON Schema")
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
        print("phongray: interrupted", file=sys.stderr)
        return 130
    except MemoryError:
        print("phongray: out of memory", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
