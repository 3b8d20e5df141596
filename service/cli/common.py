"""What every ``phongray`` command shares: the one-line error, reading and writing files, a scene loaded or
refused, the service's error answers in local words, the ``--limits`` budget."""

from __future__ import annotations

import argparse
import contextlib
import os
import stat
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from service.course.untrusted import read_own

if TYPE_CHECKING:
    from service.work.pipeline import Overrides
    from tracer.budget import OverBudget

EXIT_BAD_INPUT = 2


class CliError(Exception):
    """A user-facing failure: printed as one line, exit code attached."""

    def __init__(self, message: str, code: int = EXIT_BAD_INPUT):
        super().__init__(message)
        self.code = code


def read(path: str) -> bytes:
    try:
        return sys.stdin.buffer.read() if path == "-" else read_own(path)
    except OSError as exc:
        raise CliError(f"{path}: cannot read: {exc.strerror or exc}") from None


def read_image(path: str) -> bytes:
    """An image file, read no further than the limit ``max_image_bytes`` (an image is a student's file: a file
    without end, such as /dev/zero, must not be read whole), the same with and without ``--server``."""
    from service.course.untrusted import file_kind
    from service.settings import Settings

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


def write(path: str, data: bytes) -> None:
    try:
        if path == "-":
            sys.stdout.buffer.write(data)
            sys.stdout.flush()
        else:
            replace(Path(path), data)
    except BrokenPipeError:
        raise
    except OSError as exc:
        raise CliError(f"{path}: cannot write: {exc.strerror or exc}") from None


def replace(path: Path, data: bytes) -> None:
    """Write a file whole or not at all: a temporary file in its folder, then one rename, so that a failure (a
    full disk, an interruption) never leaves a truncated image where an old one was.  The file keeps its mode;
    a symbolic link is written through; a device or a FIFO (``/dev/null``) is written to as it is."""
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


def load(path: str, text: bytes, overrides: Overrides | None = None) -> Any:
    from service.work.pipeline import BadInput, scene_or_bad_input

    try:
        return scene_or_bad_input(path, text, overrides)
    except BadInput as exc:
        raise CliError(str(exc)) from None


def remote(scene: str, image: str | None = None) -> Any:
    """A context that turns the service's error answers into the words (and exit codes) of local work: the
    scene's problems as ``SCENE:LINE: path: message``, the image's as ``IMAGE: ...``."""
    from service.client import ServerError
    from service.work.pipeline import scene_lines

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


def cluster_client(args: argparse.Namespace) -> Any:
    from service.render.cluster import connect

    return connect(args.cluster, wait=args.cluster_wait)


def budget_of(args: argparse.Namespace, scene: Any) -> Any:
    """With ``--limits``, ``scene`` checked against the service's limits (exit 2 naming the one it exceeds) and
    the budget its render is held to; without, no limit: a scene on one's own machine is trusted."""
    from tracer.budget import UNLIMITED

    if not args.limits:
        return UNLIMITED
    from service.admission.limits import LimitError, budget, check_scene
    from service.settings import Settings

    settings = Settings.from_env()
    try:
        check_scene(scene, settings)
    except LimitError as exc:
        raise CliError(f"{args.scene}: {exc}") from None
    return budget(scene, settings)


def outgrown_error(args: argparse.Namespace, exc: OverBudget) -> CliError:
    """A render stopped by its ``--limits`` budget, in the service's words (exit 2)."""
    from service.admission.limits import outgrown
    from service.settings import Settings

    return CliError(f"{args.scene}: {outgrown(exc, Settings.from_env())}")


def thresholds(args: argparse.Namespace) -> None:
    """The grading thresholds, checked as HTTP checks them (and in the same words)."""
    for name, value, high in (("tolerance", args.tolerance, 255), ("max_fraction", args.max_fraction, 1)):
        if not 0 <= value <= high:
            raise CliError(f"{name}: must be between 0 and {high:g}")


def png_name(path: str | None) -> None:
    if path is not None and path != "-" and not path.lower().endswith(".png"):
        raise CliError(f"{path}: phongray writes PNG images; name the output *.png (or - for standard output)")
