"""The sandbox a student's program runs in: bubblewrap's command line, and the user it runs as.

Inside the sandbox a program sees, read-only, the system's programs and libraries (``/usr`` and the links
or folders ``/bin``, ``/lib``, ... beside it) and of ``/etc`` only what programs need to start (the dynamic
linker's cache and configuration, the ``alternatives`` links); ``/proc`` of its own processes, a minimal
``/dev`` (read-only but for its devices), and three size-limited tmpfs folders, the only places it can write
files: ``/tmp``, ``/dev/shm`` and its working folder ``/home/student``, which the sandbox's shell first fills
from the run's private copy of the student's folder (bound read-only at ``/submission``).  Its one scene is
``/scene/<name>``, read-only, and its output the one file ``/out/output.png``, which exists and is the only
file of the machine it can write to.  There is no network (an empty network namespace: not even the
loopback of the host), no other process of the machine, no home or work folder, nothing of the TA's
(scenes, references, reports) and no other student.  Every path above is in the sandbox; the machine's own
are the private temporary copies of :mod:`service.programs.runner`.  A runtime the TA names
(:mod:`service.programs.runtime`) is shown read-only at its own path, its ``bin`` first on the ``PATH``.
"""

from __future__ import annotations

import os
import secrets
import shutil
from dataclasses import dataclass
from pathlib import Path

from .limits import Limits

#: the working folder, in the sandbox
HOME = "/home/student"
#: where the private copy of the student's folder is bound, read-only
SUBMISSION = "/submission"
#: the folder of the one scene, and the output file, in the sandbox
SCENE_DIR = "/scene"
OUTPUT = "/out/output.png"
#: the system's folders beside /usr: bound read-only when folders, recreated when links (merged /usr)
SYSTEM = ("/bin", "/sbin", "/lib", "/lib32", "/lib64", "/libx32")
#: what of /etc a program needs: the dynamic linker's cache and configuration, the alternatives' links
#: (``/usr/bin/cc`` is a link through ``/etc/alternatives``); not the users, hosts or anything else
ETC = ("/etc/ld.so.cache", "/etc/ld.so.conf", "/etc/ld.so.conf.d", "/etc/alternatives")
ENVIRONMENT = {"PATH": "/usr/local/bin:/usr/bin:/bin", "HOME": HOME, "LANG": "C.UTF-8", "TMPDIR": "/tmp"}
#: the range the sandbox's user ids are drawn from when this process is root (no account uses them)
UID_BASE, UID_SPAN = 1_900_000_000, 100_000_000


class SandboxUnavailable(Exception):
    """A run is to be sandboxed and cannot be: bubblewrap is not installed, or cannot start a sandbox here."""


MISSING = (
    "bubblewrap (bwrap) is not installed, and students' programs only run in its sandbox: install it "
    "(apt-get install bubblewrap), or run them unsandboxed on purpose (--no-sandbox)"
)
UNSANDBOXED = (
    "WARNING: run without a sandbox: the program could read and write anything this user can, "
    "and use the network; only its limits applied"
)


def find_bwrap() -> str:
    """The path of ``bwrap``; :class:`SandboxUnavailable` when there is none."""
    found = shutil.which("bwrap")
    if found is None:
        raise SandboxUnavailable(MISSING)
    return found


def sandbox_uid() -> int:
    """The user a run's processes are, on the machine.  As root, an unused user id drawn at random for this
    run, which owns nothing of the machine and no other run's files (two runs draw the
    same id with probability 1 in 10⁸ per pair).  Not root (the autograder's unprivileged user): this
    process's own user.  Either way the run's processes are counted in its sandbox's own user namespace
    (:mod:`service.programs.guard`)."""
    if os.geteuid() != 0:
        return os.getuid()
    return UID_BASE + secrets.randbelow(UID_SPAN)


def as_user(uid: int) -> list[str]:
    """The prefix that runs what follows as ``uid`` (no groups, no new privileges), when this process is root."""
    if os.geteuid() != 0:
        return []
    return ["setpriv", f"--reuid={uid}", f"--regid={uid}", "--clear-groups", "--no-new-privs", "--"]


@dataclass(frozen=True)
class Mounts:
    """The machine's files a sandbox shows: the private copy of the student's folder, the scene's copy, and
    the output file (all in the run's temporary folder), and the TA's runtime folder."""

    submission: Path
    scene: Path | None  # None for a build, which renders no scene
    scene_name: str
    output: Path
    runtime: str | None = None  # the TA's runtime folder, shown read-only at its own path


def _system() -> list[str]:
    args = ["--ro-bind", "/usr", "/usr"]
    for path in SYSTEM:
        if os.path.islink(path):
            args += ["--symlink", os.readlink(path), path]
        elif os.path.isdir(path):
            args += ["--ro-bind", path, path]
    for path in ETC:
        args += ["--ro-bind-try", path, path]
    return args


def search_path(runtime: str | None) -> str:
    """The programs' ``PATH``: the runtime's ``bin`` first, where there is one."""
    return ENVIRONMENT["PATH"] if runtime is None else f"{runtime}/bin:{ENVIRONMENT['PATH']}"


def _environment(runtime: str | None) -> list[str]:
    args = ["--clearenv"]
    for name, value in {**ENVIRONMENT, "PATH": search_path(runtime)}.items():
        args += ["--setenv", name, value]
    return args


def bwrap_argv(bwrap: str, mounts: Mounts, limits: Limits) -> list[str]:
    """bubblewrap's arguments up to the command it runs (see the module's docstring for what they show), with
    every installation of phongray in the system's folders covered (:mod:`.hidden`)."""
    from .hidden import argv as hidden

    system = _system()
    args = [
        bwrap,
        "--unshare-all",
        "--unshare-user",
        "--disable-userns",
        "--die-with-parent",
        "--new-session",
        "--hostname",
        "sandbox",
        *_environment(mounts.runtime),
        *system,
        "--proc",
        "/proc",
        "--dev",
        "/dev",
        "--size",
        str(limits.output_bytes),
        "--tmpfs",
        "/tmp",
        "--size",
        str(limits.output_bytes),
        "--tmpfs",
        "/dev/shm",
        "--perms",
        "0700",
        "--size",
        str(limits.workdir_bytes),
        "--tmpfs",
        HOME,
        "--ro-bind",
        str(mounts.submission),
        SUBMISSION,
        "--bind",
        str(mounts.output),
        OUTPUT,
    ]
    if mounts.scene is not None:
        args += ["--ro-bind", str(mounts.scene), f"{SCENE_DIR}/{mounts.scene_name}"]
    if mounts.runtime is not None:
        args += ["--ro-bind", mounts.runtime, mounts.runtime]
    args += hidden(system, mounts.runtime)  # (after every folder shown: the runtime may hold phongray too)
    return [*args, "--remount-ro", "/dev", "--remount-ro", "/", "--chdir", HOME]
