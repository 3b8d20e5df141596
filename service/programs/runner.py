"""Run a student's program on one scene (:func:`run_program`), after building it once (:func:`build_program`).

Each run gets a temporary folder of its own on the machine, removed when the run ends however it ends: the
private copy of the student's folder (:mod:`service.programs.folder`), a copy of the scene, and the empty
output file.  The sandbox (:mod:`service.programs.sandbox`) shows the program those and the system's
programs, nothing else; the limits (:class:`~service.programs.limits.Limits`) bound what it uses.  Without
bubblewrap, a run stops with :class:`~service.programs.sandbox.SandboxUnavailable` unless it was asked to run
unsandboxed, and then every outcome carries a warning.
"""

from __future__ import annotations

import os
import shlex
import shutil
import stat
import tarfile
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path

from ..course.untrusted import UntrustedFileError, read_untrusted
from .cgroup import CgroupError
from .folder import MAX_ENTRIES, FolderTooLarge, chown_tree, copy_folder, unpack
from .guard import Guard, guard
from .limits import Limits
from .outcome import Reason, RunOutcome, failure
from .process import Command, Finished, run_command
from .sandbox import (
    ENVIRONMENT,
    OUTPUT,
    SCENE_DIR,
    UNSANDBOXED,
    Mounts,
    SandboxUnavailable,
    as_user,
    bwrap_argv,
    find_bwrap,
    sandbox_uid,
    search_path,
)
from .scripts import BUILD, BUILD_IN_PLACE, RUN, RUN_PRINTED, not_started, script, split_times
from .seccomp import filter_fd
from .watchdog import Watchdog

#: the word of a run's template that makes the program's standard output its image (in place of ``{output}``)
STDOUT = "{stdout}"


def command_argv(template: str, scene: str = "", output: str = "") -> list[str]:
    """The words of a command ``template`` (shell quoting, no shell), ``{scene}`` and ``{output}`` replaced
    in each and a ``{stdout}`` word left out; ValueError on a template that cannot be split or is empty."""
    try:
        words = shlex.split(template)
    except ValueError as exc:
        raise ValueError(f"command {template!r}: {exc}") from None
    if not words or words == [STDOUT]:
        raise ValueError("the command is empty")
    return [w.replace("{scene}", scene).replace("{output}", output) for w in words if w != STDOUT]


def prints_image(template: str) -> bool:
    """Whether a run's template makes the program's standard output its image (a ``{stdout}`` word): ValueError
    for one that names ``{stdout}`` inside a word, or names both it and ``{output}``."""
    words = shlex.split(template)
    if any(STDOUT in w and w != STDOUT for w in words):
        raise ValueError(f"command {template!r}: {STDOUT} stands alone, a word of its own")
    if STDOUT in words and any("{output}" in w for w in words):
        raise ValueError(f"command {template!r}: it names both {{output}} and {STDOUT}; the image is one of them")
    return STDOUT in words


@dataclass(frozen=True)
class ProgramRun:
    """One run: the student's folder (or a build's result), the command template (``{scene}``, ``{output}`` or
    ``{stdout}``),
    the one scene it renders, its limits, and whether it runs in the sandbox (off only on purpose)."""

    folder: Path
    command: str
    scene: Path
    limits: Limits = field(default_factory=Limits)
    sandbox: bool = True
    runtime: str | None = None  # the TA's runtime folder (:mod:`service.programs.runtime`)

    def __post_init__(self) -> None:
        """ValueError, with the template, for a command that cannot be split or names neither ``{output}`` nor
        ``{stdout}`` (the image is what the program prints)."""
        command_argv(self.command)
        if not prints_image(self.command) and "{output}" not in self.command:
            raise ValueError(
                f"command {self.command!r}: it names no {{output}}, the file the program writes (or {STDOUT}, for "
                f"a program that prints its image)"
            )


@dataclass(frozen=True)
class BuildStep:
    """The build of a student's program (``make``), run once in the same kind of sandbox as its runs."""

    folder: Path
    command: str
    limits: Limits = field(default_factory=Limits)
    sandbox: bool = True
    runtime: str | None = None

    def __post_init__(self) -> None:
        command_argv(self.command)


@dataclass(frozen=True)
class Built:
    """A build's end: its outcome, and the built folder the runs then use (None when the build failed)."""

    outcome: RunOutcome
    folder: Path | None


def _remove(root: Path) -> None:
    """Remove ``root`` and everything in it, also folders a program made unreadable (without a sandbox)."""

    def retry(function: Callable[[str], object], path: str, _exc: object) -> None:
        os.chmod(os.path.dirname(path), stat.S_IRWXU)
        function(path)

    shutil.rmtree(root, onerror=retry)


@contextmanager
def _scratch() -> Iterator[Path]:
    root = Path(tempfile.mkdtemp(prefix="phongray-run-"))
    try:
        yield root
    finally:
        _remove(root)


def _prepare(root: Path, folder: Path, scene: Path | None, limits: Limits) -> Mounts:
    """The run's folder: the copy of the student's, the scene's copy and the empty output file."""
    (root / "submission").mkdir(mode=0o700)
    copy_folder(folder, root / "submission", limits.folder_bytes)
    if scene is not None:
        shutil.copyfile(scene, root / "scene.json")
    output = root / "output.png"
    output.touch(mode=0o600)
    return Mounts(root / "submission", root / "scene.json" if scene else None, scene.name if scene else "", output)


@dataclass(frozen=True)
class _Session:
    """One sandboxed (or not) command in its run folder: what it is given, how it is limited, and the guard
    that holds its memory and processes (with the argv that runs a command under it)."""

    mounts: Mounts
    limits: Limits
    sandbox: bool
    uid: int
    guard: Guard
    guarded: list[str]


def _file_limits(session: _Session, body: str) -> tuple[int | None, int | None]:
    """The limit on one file written (``RLIMIT_FSIZE``) the command starts with, and the one the sandbox's shell
    lowers it to once the student's folder is copied in (None: no change).  A build writes its result as one
    file (:func:`built_bytes`, which holds the copy too); a sandboxed run starts with room for the copy of its
    largest file (at most the folder limit) and then has the output limit; a run in place copies nothing."""
    limits = session.limits
    if body == BUILD:
        return built_bytes(limits), None
    if session.sandbox and limits.folder_bytes > limits.output_bytes:
        return limits.folder_bytes, limits.output_bytes
    return None, None


def _command(session: _Session, words: list[str], body: str) -> Command:
    """The command line: under the guard, the limits (the address space where the watchdog holds memory;
    the processes outside the sandbox only for a user of the run's own), as the run's user, in the sandbox
    (whose own user namespace counts its processes), the shell that runs the student's command."""
    limits = session.limits
    own_user = os.geteuid() == 0
    written, lowered = _file_limits(session, body)
    outer = limits.prlimit_argv(isinstance(session.guard, Watchdog), not session.sandbox and own_user, written)
    prefix = [*session.guarded, *outer, *as_user(session.uid)]
    shell = ["/bin/sh", "-c", script(body, session.sandbox, lowered), "sh", *words]
    if not session.sandbox:
        env = {**ENVIRONMENT, "HOME": str(session.mounts.submission), "PATH": search_path(session.mounts.runtime)}
        place = str(session.mounts.submission)
        return Command([*prefix, *shell], place, env, *_kept(limits), guard=session.guard)
    bwrap = bwrap_argv(find_bwrap(), session.mounts, limits)
    seccomp = filter_fd()
    filtered = [] if seccomp is None else ["--seccomp", str(seccomp)]
    status = os.pipe()
    inner = ["prlimit", f"--nproc={limits.processes}", "--"]
    return Command(
        [*prefix, *bwrap, *filtered, "--json-status-fd", str(status[1]), *inner, *shell],
        "/",
        {"PATH": os.environ.get("PATH", "/usr/bin:/bin")},
        *_kept(limits),
        status,
        () if seccomp is None else (seccomp,),
        session.guard,
    )


def _kept(limits: Limits) -> tuple[float, int, int]:
    """A command's wall time, and how much of its standard output and error is kept: none of its standard
    output, which is the null device (a run's and a build's programs write to standard error, a printed image
    goes to its file, and a build's result to the output file)."""
    return limits.wall_seconds, 0, limits.stderr_bytes


def _execute(session: _Session, words: list[str], body: str) -> Finished:
    """Run the command; :class:`SandboxUnavailable` when the sandbox could not even start."""
    finished = run_command(_command(session, words, body))
    if session.sandbox:
        not_started(finished)
    return finished


def _outcome(
    reason: Reason, detail: str, finished: Finished | None, warning: str | None, image: bytes | None = None
) -> RunOutcome:
    if finished is None:
        return RunOutcome(reason, detail, warning=warning)
    tail, cpu = split_times(finished.stderr_tail, finished.cpu_seconds)
    return RunOutcome(reason, detail, image, tail, finished.wall_seconds, cpu, warning, finished.waited_seconds)


def _read_output(path: Path, limits: Limits) -> tuple[Reason, str, bytes | None]:
    try:
        data = read_untrusted(path, limits.output_bytes)
    except UntrustedFileError as exc:
        if "larger than the limit" in str(exc):
            return Reason.OUTPUT_TOO_LARGE, f"output larger than the limit of {limits.output_bytes} bytes", None
        if "cannot read" in str(exc):
            return Reason.NO_OUTPUT, f"no output file ({exc})", None
        return Reason.OUTPUT_NOT_REGULAR, f"the output is {exc}", None
    if not data:
        return Reason.NO_OUTPUT, "the program wrote nothing to its output file", None
    return Reason.OK, "ok", data


@contextmanager
def _session(
    folder: Path, scene: Path | None, limits: Limits, sandbox: bool, runtime: str | None
) -> Iterator[_Session]:
    """The run's folder (removed when the run ends, however it ends), given to the run's user.
    :class:`FolderTooLarge` when the student's folder is over the limit; :class:`SandboxUnavailable` when the
    run is to be sandboxed and bubblewrap is missing."""
    if sandbox:
        find_bwrap()
    uid = sandbox_uid()
    with _scratch() as root:
        mounts = replace(_prepare(root, folder, scene, limits), runtime=runtime)
        chown_tree(root, uid)
        try:
            watch, guarded = guard(limits, sandbox)
        except CgroupError as exc:
            raise SandboxUnavailable(f"the run's cgroup cannot be made: {exc}") from None
        try:
            yield _Session(mounts, limits, sandbox, uid, watch, guarded)
        finally:
            watch.close()


def run_program(run: ProgramRun) -> RunOutcome:
    """Run the program once on its scene, and say how it went (its image when it wrote one).
    :class:`SandboxUnavailable` when it is to be sandboxed and the sandbox is missing or cannot start."""
    warning = None if run.sandbox else UNSANDBOXED
    try:
        with _session(run.folder, run.scene, run.limits, run.sandbox, run.runtime) as session:
            scene = f"{SCENE_DIR}/{run.scene.name}" if run.sandbox else str(session.mounts.scene)
            output = OUTPUT if run.sandbox else str(session.mounts.output)
            words = command_argv(run.command, scene, output)
            printed = prints_image(run.command)  # (its standard output, into the output file: the same limits)
            finished = _execute(session, [output, *words] if printed else words, RUN_PRINTED if printed else RUN)
            failed = failure(finished, run.limits)
            if failed is not None:
                return _outcome(*failed, finished, warning)
            reason, detail, image = _read_output(session.mounts.output, run.limits)
            return _outcome(reason, detail, finished, warning, image)
    except FolderTooLarge as exc:
        return _outcome(Reason.FOLDER_TOO_LARGE, str(exc), None, warning)


def build_program(step: BuildStep, into: Path) -> Built:
    """Build the program once, its result put into the empty folder ``into`` (which the caller owns and
    removes): the runs then use it as their folder.  :class:`SandboxUnavailable` as for :func:`run_program`."""
    warning = None if step.sandbox else UNSANDBOXED
    try:
        with _session(step.folder, None, step.limits, step.sandbox, step.runtime) as session:
            finished = _execute(session, command_argv(step.command), BUILD if step.sandbox else BUILD_IN_PLACE)
            failed = failure(finished, step.limits)
            if failed is not None and failed[0] is Reason.OUTPUT_TOO_LARGE:  # (what a build writes is its folder)
                failed = Reason.FOLDER_TOO_LARGE, "the built folder is larger than the limit"
            if failed is None and step.sandbox:
                failed = _unpack_built(session.mounts.output, into, step.limits)
            elif failed is None:
                copy_folder(session.mounts.submission, into, step.limits.workdir_bytes)
            if failed is not None:
                return Built(_outcome(*failed, finished, warning), None)
            return Built(_outcome(Reason.OK, "built", finished, warning), into)
    except FolderTooLarge as exc:
        return Built(_outcome(Reason.FOLDER_TOO_LARGE, str(exc), None, warning), None)


def built_bytes(limits: Limits) -> int:
    """The most a build's result may take as a tar stream: its working folder, and a header for each entry."""
    return limits.workdir_bytes + MAX_ENTRIES * 1024


def _unpack_built(stream: Path, into: Path, limits: Limits) -> tuple[Reason, str] | None:
    """The build's result, the tar stream its sandbox wrote to the output file (once every other process of the
    build was killed: nothing of the student's could still write it), unpacked into ``into``; why not, when it
    cannot be read (:class:`FolderTooLarge` past the limits): the build's failure, never the class's."""
    try:
        unpack(read_untrusted(stream, built_bytes(limits)), into, limits.workdir_bytes)
    except UntrustedFileError as exc:
        return Reason.CRASHED, f"its built folder could not be read back ({exc})"
    except (tarfile.TarError, EOFError, ValueError) as exc:
        return Reason.CRASHED, f"its built folder could not be read back (not a tar stream: {exc})"
    return None


def check_sandbox(command: str = "true {output}", runtime: str | None = None) -> RunOutcome:
    """Start one sandbox that runs ``command`` (``true``): :class:`SandboxUnavailable`, with bubblewrap's own
    words, where it cannot (bubblewrap missing, or user namespaces not allowed, as in a container without the
    right), so that a batch can stop before its first student rather than fail each; else how it ran."""
    with tempfile.TemporaryDirectory(prefix="phongray-check-") as empty:
        Path(empty, "scene.json").write_text("{}")
        scene, limits = Path(empty, "scene.json"), Limits(wall_seconds=30.0)
        return run_program(ProgramRun(Path(empty), command, scene, limits, runtime=runtime))
