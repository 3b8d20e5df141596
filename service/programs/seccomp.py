"""The seccomp filter of the sandbox: which kinds of socket a student's program may make.

A renderer needs no network, and the sandbox has none (an empty network namespace); but a socket of another
family reaches the kernel's code for that family whatever the namespace holds (``AF_VSOCK`` talks to the
machine's hypervisor, ``AF_NETLINK`` to the kernel's tables, ``AF_ALG`` to its crypto, ``AF_PACKET`` and
``AF_BLUETOOTH`` to drivers), each a surface a program has no use for.  The filter lets a program make
sockets of :data:`ALLOWED` only: ``AF_UNIX`` (pipes between a program's processes: Python's
``multiprocessing``, ``socketpair``) and ``AF_INET``/``AF_INET6`` (which in the sandbox reach its own
loopback and nothing else: some runtimes open one at start to ask what the machine supports).  Any other
family fails with ``EAFNOSUPPORT``, as a family the kernel does not know does, so a program that probes one
goes on.  ``io_uring`` (which can make sockets without the ``socket`` call) fails with ``ENOSYS``, and so
does every call of the x32 ABI and, for 32-bit (i386) programs, ``socketcall``, whose arguments a filter
cannot read (such programs then have no sockets at all).

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

# classic BPF (linux/filter.h, linux/seccomp.h)
_LD_W_ABS, _JEQ_K, _JSET_K, _RET_K = 0x20, 0x15, 0x45, 0x06
_ALLOW, _ERRNO, _KILL_PROCESS = 0x7FFF0000, 0x00050000, 0x80000000
#: offsets in struct seccomp_data: the call's number, the architecture, the low 32 bits of the first argument
_NR, _ARCH = 0, 4
_ARG0 = 16 if sys.byteorder == "little" else 20
#: the x32 ABI's calls are x86-64's with this bit set
_X32 = 0x40000000
_IO_URING = (425, 426, 427)  # io_uring_setup, _enter, _register: the same numbers on every architecture


@dataclass(frozen=True)
class _Abi:
    """One ABI the kernel may see a call from: its audit architecture, its calls that make a socket (the
    family their first argument) and those refused outright."""

    arch: int
    sockets: tuple[int, ...]
    refused: tuple[int, ...]
    x32: bool = False


_X86_64 = _Abi(0xC000003E, (41, 53), _IO_URING, x32=True)  # socket, socketpair
_I386 = _Abi(0x40000003, (359, 360), (102, *_IO_URING))  # socket, socketpair; socketcall refused
_AARCH64 = _Abi(0xC00000B7, (198, 199), _IO_URING)
_ARM = _Abi(0x40000028, (281, 288), _IO_URING)
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
    asm.op(_RET_K, _ALLOW)


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
    asm.label("family")
    asm.op(_LD_W_ABS, _ARG0)
    for family in ALLOWED:
        asm.op(_JEQ_K, int(family), "allow")
    asm.op(_RET_K, _ERRNO | errno.EAFNOSUPPORT)
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
