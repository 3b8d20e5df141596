"""The sandbox's seccomp filter (service.programs.seccomp): a program makes sockets of AF_UNIX, and datagram
sockets of AF_INET and AF_INET6, only; every other family is refused as unknown, and io_uring (which makes
sockets without the call) is not there.  What would hold memory outside every process (System V shared
memory, memfds, bigger socket and pipe buffers) is refused, and so is a session of its own (the CPU's share)."""

import errno
import platform
import socket

import pytest
from test_programs import make_course, nothing_left, run  # noqa: F401  (after every test: nothing of a run left)

from service.programs import Reason
from service.programs.seccomp import ALLOWED, filter_program

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
