"""Why a sandbox cannot start, in words a teaching assistant can act on: bubblewrap's own line, and after it
the cause and the remedy where the line is one phongray knows.

* "No permissions to create new namespace" (bubblewrap blames the kernel): in a Docker container the cause is
  Docker's default seccomp profile, which refuses the namespaces bubblewrap makes; once that is lifted,
  "Can't mount proc" is the container's masked ``/proc`` paths.  Elsewhere it is the kernel's setting.
* "Resource temporarily unavailable" (on making a namespace or a process): a limit on processes was reached,
  the grading user's (``ulimit -u``) or the machine's.
"""

from __future__ import annotations

import contextlib
import os
import resource
from pathlib import Path

CONTAINER = (
    "in a container, Docker's default seccomp profile refuses the namespaces bubblewrap makes and its masked "
    "/proc paths stop it mounting /proc (the kernel is not the cause): run the container with "
    "--security-opt seccomp=unconfined --security-opt systempaths=unconfined (or --privileged), "
    "or grade with --no-sandbox"
)
KERNEL = (
    "this kernel does not let an unprivileged user make namespaces: allow it (sysctl "
    "user.max_user_namespaces=15000; on Debian before 11, kernel.unprivileged_userns_clone=1; on Ubuntu 24.04, "
    "kernel.apparmor_restrict_unprivileged_userns=0), or grade with --no-sandbox"
)
#: bubblewrap's words for each cause
NAMESPACES = ("No permissions to create new namespace", "Creating new namespace failed: Operation not permitted")
PROC = ("Can't mount proc",)
PROCESSES = ("Resource temporarily unavailable",)


def in_container() -> bool:
    """Whether this process runs in a container (Docker's marker file, or a container's cgroup of its first
    process)."""
    if Path("/.dockerenv").exists() or os.environ.get("container"):
        return True
    with contextlib.suppress(OSError):
        text = Path("/proc/1/cgroup").read_text()
        return any(word in text for word in ("docker", "containerd", "kubepods", "libpod"))
    return False


def _processes() -> str:
    soft = resource.getrlimit(resource.RLIMIT_NPROC)[0]
    limit = "unlimited" if soft == resource.RLIM_INFINITY else str(soft)
    return (
        f"a limit on processes was reached: the grading user's (ulimit -u, {limit} processes and threads) "
        f"or the machine's (kernel.pid_max, kernel.threads-max); end some, or raise it"
    )


def explain(line: str) -> str:
    """Bubblewrap's ``line``, with its cause and remedy after it where phongray knows them."""
    if any(words in line for words in NAMESPACES):
        return f"{line}; {CONTAINER if in_container() else KERNEL}"
    if any(words in line for words in PROC):
        return f"{line}; {CONTAINER}" if in_container() else line
    if any(words in line for words in PROCESSES):
        return f"{line}; {_processes()}"
    return line
