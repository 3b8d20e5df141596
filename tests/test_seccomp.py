"""The sandbox's seccomp filter (service.programs.seccomp): a program makes sockets of AF_UNIX, and datagram
sockets of AF_INET and AF_INET6, only; every other family is refused as unknown, and io_uring (which makes
sockets without the call) is not there.  What would hold memory outside every process (System V shared
memory, memfds, bigger socket and pipe buffers, inotify and fanotify queues, pages pinned in pipes, record
locks) is refused, on the 32-bit ABI too, and so is a session of its own (the CPU's share)."""

import errno
import platform
import socket
import subprocess

import numpy as np
import pytest
from test_programs import QUICK, make_course, nothing_left, run  # noqa: F401  (after every test: nothing left)

from service.programs import ProgramRun, Reason, run_program
from service.programs.seccomp import ALLOWED, filter_program
from tracer.image import encode_png

#: families a renderer has no use for, each reaching some code of the kernel's (Linux's numbers: not every
#: Python names them all)
REFUSED = {
    "AF_VSOCK": 40,
    "AF_PACKET": 17,
    "AF_NETLINK": 16,
    "AF_ALG": 38,
    "AF_BLUETOOTH": 31,
    "AF_KEY": 15,
    "AF_CAN": 29,
    "AF_TIPC": 30,
    "AF_XDP": 44,
}


@pytest.fixture
def course(tmp_path):
    """The TA's scene and a class of two students (test_programs.py's)."""
    return make_course(tmp_path)


def test_the_filter_is_built_for_this_machine():
    program = filter_program()
    assert program is not None and len(program) % 8 == 0, platform.machine()  # (8 bytes an instruction)


def test_a_program_makes_unix_and_inet_sockets_and_no_other(course):
    outcome = run(
        course,
        f"""\
        import ctypes, errno
        for name, family in {REFUSED!r}.items():
            for kind in (socket.SOCK_STREAM, socket.SOCK_DGRAM, socket.SOCK_RAW, socket.SOCK_SEQPACKET):
                try:
                    socket.socket(family, kind).close()
                    print("MADE", name, kind, file=sys.stderr)
                except OSError as exc:
                    print("REFUSED", name, kind, exc.errno, file=sys.stderr)
        one, two = socket.socketpair()
        one.sendall(b"ping")
        print("UNIX", two.recv(4).decode(), file=sys.stderr)
        for family in (socket.AF_INET, socket.AF_INET6):
            socket.socket(family, socket.SOCK_DGRAM).close()
            print("INET", family, file=sys.stderr)
        libc = ctypes.CDLL(None, use_errno=True)
        params = ctypes.create_string_buffer(120)
        made = libc.syscall(425, 4, params)  # io_uring_setup
        print("IO_URING", made, ctypes.get_errno(), file=sys.stderr)
        write_png(output)
        """,
    )
    assert outcome.reason is Reason.OK, outcome.stderr_tail
    lines = outcome.stderr_tail.splitlines()
    assert not [line for line in lines if line.startswith("MADE")]
    refused = [line.split() for line in lines if line.startswith("REFUSED")]
    assert len(refused) == 4 * len(REFUSED) and {int(r[3]) for r in refused} == {errno.EAFNOSUPPORT}
    assert "UNIX ping" in lines
    assert [line for line in lines if line.startswith("INET")] == [f"INET {int(f)}" for f in ALLOWED[1:]]
    assert f"IO_URING -1 {errno.ENOSYS}" in lines


#: every other kind of AF_INET and AF_INET6 socket: TCP, MPTCP (262), UDP-Lite (136), raw, ICMP, SOCK_PACKET (10)
INET_REFUSED = [
    (int(socket.SOCK_STREAM), 0),
    (int(socket.SOCK_STREAM), 6),
    (int(socket.SOCK_STREAM), 262),
    (int(socket.SOCK_DGRAM), 136),
    (int(socket.SOCK_DGRAM), 1),
    (int(socket.SOCK_RAW), 255),
    (10, 0),
]


def test_of_inet_only_udp_is_made(course):
    """A TCP connection over the sandbox's own loopback holds megabytes of the kernel's memory per socket; UDP
    (with or without SOCK_NONBLOCK | SOCK_CLOEXEC) is what a program that asks what the machine supports makes."""
    outcome = run(
        course,
        f"""\
        for family in (socket.AF_INET, socket.AF_INET6):
            for kind, protocol in {INET_REFUSED!r}:
                try:
                    socket.socket(family, kind, protocol).close()
                    print("MADE", family, kind, protocol, file=sys.stderr)
                except OSError as exc:
                    print("REFUSED", exc.errno, file=sys.stderr)
            for kind in (socket.SOCK_DGRAM, socket.SOCK_DGRAM | socket.SOCK_NONBLOCK | socket.SOCK_CLOEXEC):
                for protocol in (0, socket.IPPROTO_UDP):
                    socket.socket(family, kind, protocol).close()
                    print("UDP", file=sys.stderr)
        write_png(output)
        """,
    )
    assert outcome.reason is Reason.OK, outcome.stderr_tail
    lines = outcome.stderr_tail.splitlines()
    assert not [line for line in lines if line.startswith("MADE")]
    assert [line for line in lines if line.startswith("REFUSED")] == [f"REFUSED {errno.EPROTONOSUPPORT}"] * 14
    assert lines.count("UDP") == 8


def test_memory_no_process_holds_is_refused(course):
    """System V shared memory, message queues and semaphores, memfds and BPF maps are refused as a kernel without
    them refuses them; a socket's buffers stay the kernel's default and a pipe's its 64 KiB."""
    outcome = run(
        course,
        """\
        import ctypes, fcntl
        libc = ctypes.CDLL(None, use_errno=True)
        def call(name, *args):
            made = getattr(libc, name)(*args)
            print(name.upper(), made, ctypes.get_errno() if made == -1 else 0, file=sys.stderr)
        call("shmget", 0, 1 << 20, 0o1600)
        call("msgget", 0, 0o1600)
        call("semget", 0, 4, 0o1600)
        call("memfd_create", b"x", 0)
        call("syscall", 447, 0)  # memfd_secret
        call("syscall", 321, 0, 0, 0)  # bpf
        one, two = socket.socketpair()
        default = one.getsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF)
        one.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4 << 20)
        one.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
        print("SNDBUF", one.getsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF) == default, file=sys.stderr)
        one.setsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1)  # (another option is set)
        print("KEEPALIVE", one.getsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE), file=sys.stderr)
        r, w = os.pipe()
        try:
            fcntl.fcntl(w, 1031, 1 << 20)
            print("PIPE grew", file=sys.stderr)
        except OSError as exc:
            print("PIPE", exc.errno, fcntl.fcntl(w, 1032), file=sys.stderr)
        write_png(output)
        """,
    )
    assert outcome.reason is Reason.OK, outcome.stderr_tail
    lines = outcome.stderr_tail.splitlines()
    for name in ("SHMGET", "MSGGET", "SEMGET", "MEMFD_CREATE"):
        assert f"{name} -1 {errno.ENOSYS}" in lines, (name, lines)
    assert lines.count(f"SYSCALL -1 {errno.ENOSYS}") == 2
    assert "SNDBUF True" in lines and "KEEPALIVE 1" in lines
    assert f"PIPE {errno.EPERM} 65536" in lines


def test_a_program_cannot_start_sessions_of_its_own(course):
    """The kernel shares the CPU between sessions: each sandbox is one, and its processes cannot make more."""
    outcome = run(
        course,
        """\
        if os.fork() == 0:
            try:
                os.setsid()
                print("SESSION", file=sys.stderr)
            except OSError as exc:
                print("REFUSED", exc.errno, os.getsid(0) == os.getsid(os.getppid()), file=sys.stderr)
            os._exit(0)
        os.wait()
        write_png(output)
        """,
    )
    assert outcome.reason is Reason.OK, outcome.stderr_tail
    assert f"REFUSED {errno.EPERM} True" in outcome.stderr_tail.splitlines()


def test_every_thread_shares_its_processes_open_files(course):
    """The open files a run holds are counted by process: a thread of its own files (a clone without CLONE_FILES,
    unshare(CLONE_FILES)) is refused, clone3 (whose flags a filter cannot read) is not there, and threads the
    C library makes (through clone) run."""
    clone = {"x86_64": 56, "aarch64": 220}[platform.machine()]
    outcome = run(
        course,
        f"""\
        import ctypes, threading
        libc = ctypes.CDLL(None, use_errno=True)
        pid = os.fork()
        if pid == 0:  # (a child: without the filter, the bare thread would crash it)
            made = libc.syscall({clone}, 0x10000 | 0x800 | 0x100, 0, 0, 0, 0)  # clone(THREAD|SIGHAND|VM): no FILES
            print("CLONE", made, ctypes.get_errno(), file=sys.stderr, flush=True)
            os._exit(0)
        os.waitpid(pid, 0)
        made = libc.unshare(0x400)
        print("UNSHARE", made, ctypes.get_errno(), file=sys.stderr)
        made = libc.syscall(435, 0, 0)
        print("CLONE3", made, ctypes.get_errno(), file=sys.stderr)
        done = []
        thread = threading.Thread(target=lambda: done.append(1))
        thread.start()
        thread.join()
        print("THREAD", done, file=sys.stderr)
        write_png(output)
        """,
    )
    assert outcome.reason is Reason.OK, outcome.stderr_tail
    lines = outcome.stderr_tail.splitlines()
    assert f"CLONE -1 {errno.EINVAL}" in lines and f"UNSHARE -1 {errno.EPERM}" in lines
    assert f"CLONE3 -1 {errno.ENOSYS}" in lines and "THREAD [1]" in lines


def test_calls_that_queue_pin_or_split_kernel_memory_are_refused(course):
    """Events queued for inotify and fanotify, pages a pipe pins (vmsplice, splice, tee) and record locks (one
    range split into a lock a byte) are the kernel's memory, in no process's pages and with no bound of the
    run's: each call fails with ENOSYS; F_GETLK still answers, and a program still copies files and uses pipes."""
    outcome = run(
        course,
        """\
        import ctypes, fcntl, shutil
        libc = ctypes.CDLL(None, use_errno=True)
        libc.fanotify_mark.argtypes = [ctypes.c_int, ctypes.c_uint, ctypes.c_uint64, ctypes.c_int, ctypes.c_char_p]
        libc.splice.argtypes = [ctypes.c_int, ctypes.c_void_p, ctypes.c_int, ctypes.c_void_p, ctypes.c_size_t,
                                ctypes.c_uint]
        def call(name, *args):
            made = getattr(libc, name)(*args)
            print(name.upper(), made, ctypes.get_errno() if made == -1 else 0, file=sys.stderr)
        r, w = os.pipe()
        r2, w2 = os.pipe()
        page = ctypes.create_string_buffer(4096)
        iov = (ctypes.c_void_p * 2)(ctypes.addressof(page), 4096)
        call("inotify_init1", 0)
        call("inotify_add_watch", -1, b"/tmp", 0xFFF)
        call("fanotify_init", 0x00000C00, os.O_RDONLY)  # (FAN_REPORT_DFID_NAME: allowed to anyone)
        call("fanotify_mark", -1, 1, 0x100, -100, b"/tmp")
        call("vmsplice", w, iov, 1, 0)
        os.write(w, b"x" * 100)
        call("tee", r, w2, 100, 0)
        call("splice", r, None, w2, None, 100, 0)
        fd = os.open("/tmp/locked", os.O_CREAT | os.O_RDWR)
        for name, command in (("SETLK", 6), ("SETLKW", 7), ("OFD_SETLK", 37), ("OFD_SETLKW", 38), ("GETLK", 5),
                              ("OFD_GETLK", 36)):
            try:
                fcntl.fcntl(fd, command, bytes(32))  # (a read lock of the whole file)
                print("LOCK", name, 0, file=sys.stderr)
            except OSError as exc:
                print("LOCK", name, exc.errno, file=sys.stderr)
        for name, lock in (("FLOCK", fcntl.flock), ("LOCKF", fcntl.lockf)):
            try:
                lock(fd, fcntl.LOCK_EX)
                print(name, 0, file=sys.stderr)
            except OSError as exc:
                print(name, exc.errno, file=sys.stderr)
        shutil.copyfile("render.py", "/tmp/copy.py")
        print("COPIED", open("/tmp/copy.py").read() == open("render.py").read(), file=sys.stderr)
        print("PIPE", os.read(r, 200), file=sys.stderr)
        write_png(output)
        """,
    )
    assert outcome.reason is Reason.OK, outcome.stderr_tail
    lines = outcome.stderr_tail.splitlines()
    refused = ("INOTIFY_INIT1", "INOTIFY_ADD_WATCH", "FANOTIFY_INIT", "FANOTIFY_MARK", "VMSPLICE", "TEE", "SPLICE")
    for name in refused:
        assert f"{name} -1 {errno.ENOSYS}" in lines, (name, lines)
    for name in ("SETLK", "SETLKW", "OFD_SETLK", "OFD_SETLKW"):
        assert f"LOCK {name} {errno.ENOSYS}" in lines, (name, lines)
    assert f"FLOCK {errno.ENOSYS}" in lines and f"LOCKF {errno.ENOSYS}" in lines
    assert "LOCK GETLK 0" in lines and "LOCK OFD_GETLK 0" in lines
    assert "COPIED True" in lines and f"PIPE {b'x' * 100!r}" in lines


#: a C program's calls through the 32-bit ABI (``int $0x80`` from a 64-bit process: the kernel sees i386's
#: calls and numbers), each call's result (a negative errno) on a line; the lock's record is in static memory,
#: below 4 GiB in a program linked without PIE
I386_PROBE = r"""
#include <fcntl.h>
#include <stdio.h>
#include <unistd.h>
static char record[32];
static long i386(long n, long a, long b, long c) {
    long r;
    __asm__ volatile ("int $0x80" : "=a"(r) : "a"(n), "b"(a), "c"(b), "d"(c) : "memory");
    return r;
}
int main(int argc, char **argv) {
    int fd = open("/tmp/locked", O_CREAT | O_RDWR, 0600), p[2];
    long at = (long)record;
    char image[4096];
    if (pipe(p) != 0) return 1;
    fprintf(stderr, "FCNTL64_SETLK64 %ld\n", i386(221, fd, 13, at));
    fprintf(stderr, "FCNTL64_SETLKW64 %ld\n", i386(221, fd, 14, at));
    fprintf(stderr, "FCNTL64_SETLK %ld\n", i386(221, fd, 6, at));
    fprintf(stderr, "FCNTL_SETLKW %ld\n", i386(55, fd, 7, at));
    fprintf(stderr, "FCNTL64_OFD_SETLK %ld\n", i386(221, fd, 37, at));
    fprintf(stderr, "FCNTL64_GETLK64 %ld\n", i386(221, fd, 12, at));
    fprintf(stderr, "FCNTL_SETPIPE_SZ %ld\n", i386(55, p[1], 1031, 1 << 20));
    fprintf(stderr, "FLOCK %ld\n", i386(143, fd, 2, 0));
    fprintf(stderr, "INOTIFY_INIT1 %ld\n", i386(332, 0, 0, 0));
    fprintf(stderr, "FANOTIFY_INIT %ld\n", i386(338, 0xC00, 0, 0));
    fprintf(stderr, "VMSPLICE %ld\n", i386(316, -1, 0, 0));
    FILE *in = fopen("image.png", "rb"), *out = fopen(argv[2], "wb");
    size_t n = fread(image, 1, sizeof image, in);
    fwrite(image, 1, n, out);
    fclose(out);
    return 0;
}
"""


def test_the_32_bit_abi_is_refused_the_same_calls(course, tmp_path):
    """A 64-bit program may make i386's calls (``int $0x80``), whose numbers and fcntl commands are i386's
    (fcntl64, F_SETLK64): the filter checks them as that ABI's; F_GETLK64 still answers."""
    assert platform.machine() == "x86_64", "the 32-bit probe is written for x86-64"
    folder = course / "subs" / "ann"
    source = tmp_path / "probe.c"
    source.write_text(I386_PROBE)
    subprocess.run(["gcc", "-O1", "-no-pie", "-o", folder / "probe", source], check=True)
    (folder / "image.png").write_bytes(encode_png(np.zeros((3, 4, 3), np.uint8)))
    outcome = run_program(ProgramRun(folder, "./probe {scene} {output}", course / "scenes" / "spheres.json", QUICK))
    assert outcome.reason is Reason.OK, outcome.stderr_tail
    lines = outcome.stderr_tail.splitlines()
    refused = ("SETLK64", "SETLKW64", "SETLK", "OFD_SETLK")
    for name in [f"FCNTL64_{name}" for name in refused] + ["FCNTL_SETLKW", "FLOCK", "INOTIFY_INIT1"]:
        assert f"{name} {-errno.ENOSYS}" in lines, (name, lines)
    assert f"FANOTIFY_INIT {-errno.ENOSYS}" in lines and f"VMSPLICE {-errno.ENOSYS}" in lines
    assert "FCNTL64_GETLK64 0" in lines and f"FCNTL_SETPIPE_SZ {-errno.EPERM}" in lines
