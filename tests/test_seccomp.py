"""The sandbox's seccomp filter (service.programs.seccomp): a program makes sockets of AF_UNIX, AF_INET and
AF_INET6 only; every other family is refused as unknown, and io_uring (which makes sockets without the call)
is not there."""

import errno
import platform

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
            socket.socket(family, socket.SOCK_STREAM).close()
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
