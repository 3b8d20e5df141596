"""The seccomp filter of the sandbox: which kinds of socket a student's program may make, and the few calls that
would let it hold memory no limit of the run sees, or take more than its share of the CPU.

A renderer needs no network, and the sandbox has none (an empty network namespace); but a socket of another
family reaches the kernel's code for that family whatever the namespace holds (``AF_VSOCK`` talks to the
machine's hypervisor, ``AF_NETLINK`` to the kernel's tables, ``AF_ALG`` to its crypto, ``AF_PACKET`` and
``AF_BLUETOOTH`` to drivers), each a surface a program has no use for.  The filter lets a program make
sockets of :data:`ALLOWED` only: ``AF_UNIX`` (pipes between a program's processes: Python's
``multiprocessing``, ``socketpair``) and ``AF_INET``/``AF_INET6`` datagram sockets (UDP, which in the sandbox
reach its own loopback and nothing else: some runtimes open one at start to ask what the machine supports).
Any other family fails with ``EAFNOSUPPORT``, as a family the kernel does not know does, so a program that
probes one goes on; an ``AF_INET``/``AF_INET6`` socket of another kind (TCP, MPTCP, UDP-Lite, raw, ICMP,
``SOCK_PACKET``) fails with ``EPROTONOSUPPORT``: a TCP connection over the sandbox's own loopback could hold
megabytes of the kernel's memory per socket.  ``io_uring`` (which can make sockets without the ``socket``
call) fails with ``ENOSYS``, and so does every call of the x32 ABI and, for 32-bit (i386) programs,
``socketcall`` and ``ipc``, whose arguments a filter cannot read (such programs then have no sockets at all).

The memory a process holds is what the run's guard counts (:mod:`service.programs.watchdog`); the filter
refuses what would hold memory outside every process, with no bound of the run's: System V shared memory,
message queues and semaphores (``shmget``, ``msgget``, ``semget``), ``memfd_create`` and ``memfd_secret``
(files in memory, which no folder's size holds) and ``bpf`` (its maps), each with ``ENOSYS``, as a kernel
built without them answers; a socket's buffer stays the kernel's default (``setsockopt``'s ``SO_SNDBUF`` and
``SO_RCVBUF`` are ignored, as the kernel ignores a value over its maximum) and a pipe's its default 64 KiB
(``fcntl``'s ``F_SETPIPE_SZ`` fails with ``EPERM``, as it does past the user's limit), so that each open
file holds at most a known amount (:data:`service.programs.usage.FILE_BYTES`); and every thread shares its
process's open files (a ``clone`` of a thread without ``CLONE_FILES`` fails with ``EINVAL``,
``unshare(CLONE_FILES)`` with ``EPERM``, ``clone3``, whose flags a filter cannot read, with ``ENOSYS``, after
which the C library uses ``clone``), so that the open files counted by process are all of them.  Three more kinds
of the kernel's memory grow within one open file past what it counts, and a renderer needs none of them: the
events queued for an inotify or fanotify instance (16,384 of up to ~500 bytes each, ~8 MiB an instance:
``inotify_init``, ``inotify_init1``, ``inotify_add_watch``, ``fanotify_init``, ``fanotify_mark``); the pages a
pipe pins (``vmsplice`` puts a page of the program's in each of a pipe's 16 buffers, and the whole of a 2 MiB
huge page stays with it, 32 MiB a pipe no process maps; ``splice`` and ``tee`` would move or copy such buffers
between pipes); and record locks, which one range unlocked byte by byte splits into a lock a byte, with no
bound (``fcntl``'s ``F_SETLK``, ``F_SETLKW``, their 64-bit forms and ``F_OFD_SETLK``, ``F_OFD_SETLKW``; and
``flock``).  Each fails with ``ENOSYS``, as on a kernel or a file system without them, on which a program that
tries them goes on without (copying with ``read`` and ``write``, working unlocked: a run is one program, and
its processes' files are their own); ``F_GETLK`` still answers (nothing is locked).  ``setsid`` fails with
``EPERM``: the kernel shares the CPU between sessions (autogroups), and each sandbox is one session
(bubblewrap's ``--new-session``), so a program cannot take another run's share by making more.

The filter is classic BPF, built here once per architecture (x86-64 and arm64, with their 32-bit ABIs) and
handed to bubblewrap's ``--seccomp``, which loads it just before the program starts; every process of the
run inherits it and cannot lift it.  On another architecture there is no filter (:func:`filter_program`
returns None) and the sandbox is otherwise the same.
"""

from __future__ import annotations

import errno
import os
import platform
import socket
import struct
import sys
from dataclasses import dataclass
from functools import cache

#: the socket families a program may make (see the module's docstring)
ALLOWED = (socket.AF_UNIX, socket.AF_INET, socket.AF_INET6)
#: of AF_INET and AF_INET6, the one kind of socket allowed (its type, under SOCK_NONBLOCK and SOCK_CLOEXEC) and
#: its protocols (the default, and UDP)
INET_TYPE, INET_PROTOCOLS = int(socket.SOCK_DGRAM), (0, int(socket.IPPROTO_UDP))
#: setsockopt's level and names that would grow a socket's buffers (Linux's numbers, on every architecture)
SOL_SOCKET, BUFFERS = 1, (7, 8)  # SO_SNDBUF, SO_RCVBUF
F_SETPIPE_SZ = 1031
#: fcntl's commands that take a record lock (F_SETLK, F_SETLKW, their 64-bit forms of 32-bit ABIs, F_OFD_SETLK,
#: F_OFD_SETLKW: the same numbers on every architecture here); F_GETLK and F_OFD_GETLK only ask, and stay
LOCKS = (6, 7, 13, 14, 37, 38)

# classic BPF (linux/filter.h, linux/seccomp.h)
_LD_W_ABS, _JEQ_K, _JSET_K, _AND_K, _RET_K = 0x20, 0x15, 0x45, 0x54, 0x06
_ALLOW, _ERRNO, _KILL_PROCESS = 0x7FFF0000, 0x00050000, 0x80000000
#: offsets in struct seccomp_data: the call's number, the architecture
_NR, _ARCH = 0, 4
#: the x32 ABI's calls are x86-64's with this bit set
_X32 = 0x40000000
#: refused on every architecture, by the same numbers: io_uring_setup, _enter, _register; clone3 (whose flags a
#: filter cannot read: the C library then uses clone); memfd_secret
_REFUSED = (425, 426, 427, 435, 447)
#: clone's flags: a thread (CLONE_THREAD) shares its process's open files (CLONE_FILES)
CLONE_THREAD, CLONE_FILES = 0x10000, 0x400


def _arg(n: int) -> int:
    """The offset of the low 32 bits of the call's argument ``n`` in struct seccomp_data."""
    return 16 + 8 * n + (0 if sys.byteorder == "little" else 4)


@dataclass(frozen=True)
class _Abi:
    """One ABI the kernel may see a call from: its audit architecture, its calls that make a socket (the
    family their first argument), those refused outright (``ENOSYS``), and its ``setsid``, ``setsockopt``
    and ``fcntl`` calls."""

    arch: int
    sockets: tuple[int, ...]
    refused: tuple[int, ...]
    setsid: int
    setsockopt: int
    fcntl: tuple[int, ...]
    clone: tuple[int, int]  # clone, unshare
    x32: bool = False


# refused: io_uring and clone3; shmget, msgget, semget (and i386's ipc); memfd_create, memfd_secret; bpf; then
# inotify_init, inotify_init1, inotify_add_watch, fanotify_init, fanotify_mark (aarch64 has no inotify_init);
# splice, tee, vmsplice; flock
_X86_64 = _Abi(
    0xC000003E,
    (41, 53),
    (*_REFUSED, 29, 68, 64, 319, 321, 253, 294, 254, 300, 301, 275, 276, 278, 73),
    112,
    54,
    (72,),
    (56, 272),
    x32=True,
)
_I386 = _Abi(
    0x40000003,
    (359, 360),
    (102, 117, *_REFUSED, 395, 399, 393, 356, 357, 291, 332, 292, 338, 339, 313, 315, 316, 143),
    66,
    366,
    (55, 221),
    (120, 310),
)
_AARCH64 = _Abi(
    0xC00000B7,
    (198, 199),
    (*_REFUSED, 194, 186, 190, 279, 280, 26, 27, 262, 263, 76, 77, 75, 32),
    157,
    208,
    (25,),
    (220, 97),
)
_ARM = _Abi(
    0x40000028,
    (281, 288),
    (*_REFUSED, 307, 303, 299, 385, 386, 316, 360, 317, 367, 368, 340, 342, 343, 143),
    66,
    294,
    (55, 221),
    (120, 337),
)
ABIS = {"x86_64": (_X86_64, _I386), "amd64": (_X86_64, _I386), "aarch64": (_AARCH64, _ARM), "arm64": (_AARCH64, _ARM)}


class _Assembler:
    """Instructions with forward jumps to labels, resolved into BPF's relative offsets."""

    def __init__(self) -> None:
        self.code: list[tuple[int, str | None, str | None, int]] = []
        self.labels: dict[str, int] = {}

    def op(self, code: int, k: int, true: str | None = None, false: str | None = None) -> None:
        self.code.append((code, true, false, k))

    def label(self, name: str) -> None:
        self.labels[name] = len(self.code)

    def bytes(self) -> bytes:
        out = b""
        for at, (code, true, false, k) in enumerate(self.code):
            jt, jf = (0 if name is None else self.labels[name] - at - 1 for name in (true, false))
            assert 0 <= jt < 256 and 0 <= jf < 256
            out += struct.pack("=HBBI", code, jt, jf, k)
        return out


def _abi(asm: _Assembler, abi: _Abi, n: int) -> None:
    """The checks of one ABI's calls; at its label ``abi{n}``, with the call's number not yet loaded."""
    asm.label(f"abi{n}")
    asm.op(_LD_W_ABS, _NR)
    if abi.x32:
        asm.op(_JSET_K, _X32, "enosys")
    for number in abi.sockets:
        asm.op(_JEQ_K, number, "family")
    for number in abi.refused:
        asm.op(_JEQ_K, number, "enosys")
    asm.op(_JEQ_K, abi.setsid, "eperm")
    asm.op(_JEQ_K, abi.setsockopt, "sockopt")
    for number in abi.fcntl:
        asm.op(_JEQ_K, number, "fcntl")
    asm.op(_JEQ_K, abi.clone[0], "clone")
    asm.op(_JEQ_K, abi.clone[1], "unshare")
    asm.op(_RET_K, _ALLOW)


def _sockets(asm: _Assembler) -> None:
    """A socket's family (and, of AF_INET and AF_INET6, its type and protocol) checked; at ``family``."""
    asm.label("family")
    asm.op(_LD_W_ABS, _arg(0))
    asm.op(_JEQ_K, int(socket.AF_UNIX), "allow")
    for family in ALLOWED[1:]:
        asm.op(_JEQ_K, int(family), "inet")
    asm.op(_RET_K, _ERRNO | errno.EAFNOSUPPORT)
    asm.label("inet")
    asm.op(_LD_W_ABS, _arg(1))
    asm.op(_AND_K, 0xF)  # (SOCK_TYPE_MASK: the flags above it are SOCK_NONBLOCK and SOCK_CLOEXEC)
    asm.op(_JEQ_K, INET_TYPE, "protocol")
    asm.op(_RET_K, _ERRNO | errno.EPROTONOSUPPORT)
    asm.label("protocol")
    asm.op(_LD_W_ABS, _arg(2))
    for protocol in INET_PROTOCOLS:
        asm.op(_JEQ_K, protocol, "allow")
    asm.op(_RET_K, _ERRNO | errno.EPROTONOSUPPORT)


def _buffers(asm: _Assembler) -> None:
    """``setsockopt(SOL_SOCKET, SO_SNDBUF or SO_RCVBUF)`` ignored (at ``sockopt``) and ``fcntl(F_SETPIPE_SZ)``
    refused (at ``fcntl``)."""
    asm.label("sockopt")
    asm.op(_LD_W_ABS, _arg(1))
    asm.op(_JEQ_K, SOL_SOCKET, "optname", "allow")
    asm.label("optname")
    asm.op(_LD_W_ABS, _arg(2))
    for name in BUFFERS:
        asm.op(_JEQ_K, name, "ignored")
    asm.op(_RET_K, _ALLOW)
    asm.label("ignored")
    asm.op(_RET_K, _ERRNO | 0)  # (the call returns 0, having done nothing)
    asm.label("fcntl")
    asm.op(_LD_W_ABS, _arg(1))
    for command in LOCKS:
        asm.op(_JEQ_K, command, "enosys")
    asm.op(_JEQ_K, F_SETPIPE_SZ, "eperm", "allow")


def _files(asm: _Assembler) -> None:
    """A thread of its own open files refused: ``clone`` of a thread without ``CLONE_FILES`` (``EINVAL``, at
    ``clone``), ``unshare(CLONE_FILES)`` (``EPERM``, at ``unshare``); so that the open files a run holds are
    its processes' (:mod:`service.programs.usage` counts them by process)."""
    asm.label("clone")
    asm.op(_LD_W_ABS, _arg(0))
    asm.op(_AND_K, CLONE_THREAD | CLONE_FILES)
    asm.op(_JEQ_K, CLONE_THREAD, "einval", "allow")
    asm.label("unshare")
    asm.op(_LD_W_ABS, _arg(0))
    asm.op(_JSET_K, CLONE_FILES, "eperm", "allow")


def build(abis: tuple[_Abi, ...]) -> bytes:
    """The filter's program for a machine whose calls come from ``abis`` (a call of any other architecture
    kills the process: the kernel has none)."""
    asm = _Assembler()
    asm.op(_LD_W_ABS, _ARCH)
    for n, abi in enumerate(abis):
        asm.op(_JEQ_K, abi.arch, f"abi{n}")
    asm.op(_RET_K, _KILL_PROCESS)
    for n, abi in enumerate(abis):
        _abi(asm, abi, n)
    _sockets(asm)
    _buffers(asm)
    _files(asm)
    asm.label("einval")
    asm.op(_RET_K, _ERRNO | errno.EINVAL)
    asm.label("eperm")
    asm.op(_RET_K, _ERRNO | errno.EPERM)
    asm.label("allow")
    asm.op(_RET_K, _ALLOW)
    asm.label("enosys")
    asm.op(_RET_K, _ERRNO | errno.ENOSYS)
    return asm.bytes()


@cache
def filter_program() -> bytes | None:
    """The filter for this machine's architecture; None where phongray has none (see the module)."""
    abis = ABIS.get(platform.machine().lower())
    return None if abis is None else build(abis)


def filter_fd() -> int | None:
    """A file descriptor to read the filter from, at its start (the caller passes it to bubblewrap, then
    closes it); None where there is no filter."""
    program = filter_program()
    if program is None:
        return None
    fd = os.memfd_create("phongray-seccomp", os.MFD_CLOEXEC)
    os.write(fd, program)
    os.lseek(fd, 0, os.SEEK_SET)
    return fd
