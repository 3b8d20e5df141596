"""Students' programs in the sandbox (service.programs): an honest one renders, hostile ones are contained.

Each program is a Python script written here into a student's folder and run by the system's python3 in
the sandbox (a program sees /usr, not this project's virtual environment: it writes its PNG with zlib and
struct).  Each test asserts the outcome's reason, and what a hostile program could see or leave behind."""

import os
import shutil
import socket
import tempfile
import textwrap
import threading
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from service.programs import (
    BuildStep,
    Limits,
    ProgramRun,
    Reason,
    SandboxUnavailable,
    build_program,
    check_sandbox,
    run_program,
)

from helpers import left_in_sandboxes

#: a small PNG writer every test program starts with: write_png(path) writes a 4×3 red image
PRELUDE = textwrap.dedent("""\
    import os, socket, struct, sys, time, zlib
    def write_png(path):
        def chunk(kind, data):
            return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
        rows = b"".join(b"\\0" + b"\\xff\\0\\0" * 4 for _ in range(3))
        with open(path, "wb") as f:
            f.write(b"\\x89PNG\\r\\n\\x1a\\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 4, 3, 8, 2, 0, 0, 0))
                    + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))
    scene, output = sys.argv[1], sys.argv[2]
    """)
SECRET = "TA-SECRET-7f3a91"
#: short limits, so that a hostile program is stopped in seconds
QUICK = Limits(wall_seconds=5.0, cpu_seconds=10, memory_bytes=512 << 20, output_bytes=8 << 20, folder_bytes=4 << 20)


@pytest.fixture
def course(tmp_path):
    return make_course(tmp_path)


def make_course(tmp_path: Path) -> Path:
    """The TA's scene folder (with a secret reference) and a class of two students: 'ann' (the one run) and
    'bob', whose folder holds his own secret."""
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    (scenes / "spheres.json").write_text('{"scene": "spheres"}\n')
    (scenes / "reference.txt").write_text(SECRET)
    for name in ("ann", "bob"):
        (tmp_path / "subs" / name).mkdir(parents=True)
    (tmp_path / "subs" / "bob" / "render.py").write_text(f"# {SECRET}\n")
    return tmp_path


def run(course: Path, body: str, limits: Limits = QUICK, sandbox: bool = True):
    (course / "subs" / "ann" / "render.py").write_text(PRELUDE + textwrap.dedent(body))
    return run_program(
        ProgramRun(
            course / "subs" / "ann",
            "python3 render.py {scene} {output}",
            course / "scenes" / "spheres.json",
            limits,
            sandbox,
        )
    )


def left_running(word: str | None = None) -> list[str]:
    """What this test's runs left running: a sandbox or anything under it, or a process whose command line
    holds ``word``; zombies do not count (a zombie runs nothing and holds no memory)."""
    return left_in_sandboxes(word)


def runs_on_disk() -> set[str]:
    return {p.name for p in Path(tempfile.gettempdir()).glob("phongray-run-*")}


@pytest.fixture(autouse=True)
def nothing_left():
    """After every test: no run's folder left on the disk, no sandboxed process left running."""
    before = runs_on_disk()
    yield
    assert runs_on_disk() <= before
    assert left_running() == []


def test_an_honest_program_renders_its_scene(course):
    outcome = run(
        course,
        """\
        print(open(scene).read(), os.listdir("."), file=sys.stderr)
        write_png(output)
        """,
    )
    assert outcome.reason is Reason.OK and outcome.warning is None
    assert '{"scene": "spheres"}' in outcome.stderr_tail and "['render.py']" in outcome.stderr_tail
    assert np.array_equal(outcome.pixels()[0, 0], [255, 0, 0]) and outcome.pixels().shape == (3, 4, 3)
    assert outcome.wall_seconds > 0


def test_what_a_program_sees_of_the_machine(course):
    targets = [
        course / "scenes" / "reference.txt",
        course / "subs" / "bob" / "render.py",
        course,
        "/work",
        "/root",
        "/etc/passwd",
        "/etc/shadow",
        "/tmp",
        str(Path(__file__).resolve()),
    ]
    (course / "subs" / "ann" / "peek").symlink_to(course / "scenes" / "reference.txt")
    outcome = run(
        course,
        f"""\
        for path in {[str(t) for t in targets]!r} + ["peek", "/scene"]:
            try:
                seen = os.listdir(path) if os.path.isdir(path) else open(path).read()
            except OSError as exc:
                seen = type(exc).__name__
            print("SAW", path, seen, file=sys.stderr)
        write_png(output)
        """,
    )
    assert outcome.reason is Reason.OK
    assert SECRET not in outcome.stderr_tail
    seen = dict(line.split(" ", 2)[1:] for line in outcome.stderr_tail.splitlines() if line.startswith("SAW"))
    for target in targets:
        assert seen[str(target)] in ("FileNotFoundError", "[]"), (target, seen[str(target)])
    assert seen["peek"] == "FileNotFoundError"  # the student's link was not copied
    assert seen["/scene"] == "['spheres.json']"


def test_no_network_not_even_the_machines_loopback(course):
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen()
    listener.settimeout(3.0)
    port = listener.getsockname()[1]
    accepted: list[object] = []
    thread = threading.Thread(target=lambda: accepted.append(_accept(listener)))
    thread.start()
    outcome = run(
        course,
        f"""\
        try:
            socket.create_connection(("127.0.0.1", {port}), timeout=2).sendall(b"{SECRET}")
            print("CONNECTED", file=sys.stderr)
        except OSError as exc:
            print("REFUSED", exc, file=sys.stderr)
        write_png(output)
        """,
    )
    thread.join()
    listener.close()
    assert outcome.reason is Reason.OK and "REFUSED" in outcome.stderr_tail
    assert accepted == [None]


def _accept(listener: socket.socket) -> object:
    try:
        return listener.accept()
    except TimeoutError:
        return None


def test_an_endless_loop_is_stopped_at_the_wall_time_limit(course):
    outcome = run(course, "while True: pass\n", Limits(wall_seconds=2.0, cpu_seconds=60))
    assert outcome.reason is Reason.TIMEOUT and outcome.image is None
    assert 2.0 <= outcome.wall_seconds < 30


def test_a_loop_is_stopped_at_the_cpu_time_limit(course):
    outcome = run(course, "while True: pass\n", Limits(wall_seconds=60.0, cpu_seconds=1))
    assert outcome.reason is Reason.CPU_TIME
    # the time comes from the sandbox's report (the parent's own wait4 sees almost none of it: bubblewrap does
    # not reap the sandbox); the kernel's accounting of the limit and the shell's `times` differ by ticks, so
    # the test asks for most of the second, which without the report would read a few milliseconds
    assert outcome.cpu_seconds > 0.5


def test_the_process_limit_bites(course):
    outcome = run(
        course,
        """\
        made = 0
        try:
            while made < 200:
                if os.fork() == 0:
                    time.sleep(30)
                    os._exit(0)
                made += 1
        except OSError as exc:
            print("FORKS", made, exc, file=sys.stderr)
        write_png(output)
        """,
        Limits(processes=16, wall_seconds=20.0),
    )
    assert outcome.reason is Reason.OK  # (the run ends when the program does: its children with it)
    made = int(outcome.stderr_tail.split("FORKS ")[1].split()[0])
    assert 0 < made < 16


def test_a_fork_bomb_is_contained_and_nothing_is_left_running(course):
    outcome = run(
        course,
        """\
        while True:
            try:
                os.fork()
            except OSError:
                pass
        """,
        Limits(processes=32, wall_seconds=3.0),
    )
    assert outcome.reason is Reason.TIMEOUT
    # (the autouse fixture checks that no process of the run is left)


def test_a_memory_hog_runs_out_of_memory(course):
    outcome = run(
        course,
        """\
        hoard = []
        while True:
            hoard.append(bytearray(16 << 20))
        """,
        Limits(memory_bytes=256 << 20),
    )
    assert outcome.reason is Reason.MEMORY


def test_a_5_GB_output_file_is_stopped_at_the_output_limit(course):
    outcome = run(
        course,
        """\
        with open(output, "wb") as f:
            for _ in range(5 * 1024):
                f.write(b"x" * (1 << 20))
        """,
    )
    assert outcome.reason is Reason.OUTPUT_TOO_LARGE


def test_many_files_fill_only_their_own_tmpfs(course):
    outcome = run(
        course,
        """\
        for i in range(5 * 1024):
            with open(f"junk{i}", "wb") as f:
                f.write(b"x" * (4 << 20))
        """,
    )
    assert outcome.reason is Reason.OUTPUT_TOO_LARGE and "No space left" in outcome.stderr_tail


def test_a_daemon_left_running_is_gone_after_the_run(course):
    outcome = run(
        course,
        """\
        if os.fork() == 0:
            try:
                os.setsid()  # (refused in the sandbox: the double fork still makes a daemon)
            except OSError:
                pass
            if os.fork() == 0:
                os.execvp("sleep", ["sleep", "987.654"])
            os._exit(0)
        os.wait()
        write_png(output)
        """,
    )
    assert outcome.reason is Reason.OK
    assert left_running("987.654") == []


def test_an_output_that_is_a_link_to_etc_passwd_is_not_read(course):
    body = """\
        try:
            os.remove(output)
            os.symlink("/etc/passwd", output)
        except OSError as exc:
            print("CANNOT", exc, file=sys.stderr)
        """
    outcome = run(course, body)
    assert outcome.reason is Reason.NO_OUTPUT and "CANNOT" in outcome.stderr_tail  # (its output is a mount)
    unsandboxed = run(course, body, sandbox=False)
    assert unsandboxed.reason is Reason.OUTPUT_NOT_REGULAR and unsandboxed.image is None
    assert "symbolic link" in unsandboxed.detail and unsandboxed.warning


def test_a_crash_is_named_by_its_exit_status_or_signal(course):
    assert run(course, "sys.exit(3)\n").detail == "crashed (exit 3)"
    crashed = run(course, "os.kill(os.getpid(), 11)\n")
    assert crashed.reason is Reason.CRASHED and crashed.detail == "crashed (killed by SIGSEGV)"


def test_a_folder_larger_than_the_limit_is_not_run(course):
    (course / "subs" / "ann" / "data.bin").write_bytes(b"\0" * (QUICK.folder_bytes + 1))
    assert run(course, "write_png(output)\n").reason is Reason.FOLDER_TOO_LARGE


def test_a_file_larger_than_the_output_limit_in_the_folder_is_copied_and_read(course):
    """A student's file within the folder limit but larger than the output limit (a library, a mesh) is
    copied into the run and read; what the program writes is then held to the output limit, soft and hard."""
    limits = replace(QUICK, output_bytes=1 << 20, folder_bytes=4 << 20)
    (course / "subs" / "ann" / "mesh.bin").write_bytes(b"\1" * (3 << 20))
    outcome = run(
        course,
        """\
        import resource
        print("read", len(open("mesh.bin", "rb").read()), resource.getrlimit(resource.RLIMIT_FSIZE), file=sys.stderr)
        write_png(output)
        """,
        limits,
    )
    assert outcome.reason is Reason.OK, outcome.stderr_tail
    assert f"read {3 << 20} ({1 << 20}, {1 << 20})" in outcome.stderr_tail
    written = run(course, 'open("copy.bin", "wb").write(b"x" * (2 << 20))\nwrite_png(output)\n', limits)
    assert written.reason is Reason.OUTPUT_TOO_LARGE


def test_without_bubblewrap_only_an_unsandboxed_run_goes_on(course, monkeypatch):
    monkeypatch.setattr(shutil, "which", lambda name: None)
    with pytest.raises(SandboxUnavailable, match="--no-sandbox"):
        run(course, "write_png(output)\n")
    outcome = run(course, "write_png(output)\n", sandbox=False)
    assert outcome.reason is Reason.OK and "without a sandbox" in (outcome.warning or "")


def test_a_build_runs_once_and_its_result_is_what_runs(course, tmp_path):
    ann = course / "subs" / "ann"
    (ann / "Makefile").write_text(
        "render.py: template.py\n\tsed s/COLOUR/ff/ template.py > render.py\n\tln -s /etc/passwd passwd\n"
    )
    (ann / "template.py").write_text(PRELUDE + "write_png(output)  # COLOUR\n")
    built = build_program(BuildStep(ann, "make", QUICK), tmp_path / "built")
    assert built.outcome.reason is Reason.OK and built.folder is not None
    assert sorted(os.listdir(built.folder)) == ["Makefile", "render.py", "template.py"]  # (not the link)
    assert "# ff" in (built.folder / "render.py").read_text()
    outcome = run_program(
        ProgramRun(built.folder, "python3 render.py {scene} {output}", course / "scenes" / "spheres.json", QUICK)
    )
    assert outcome.reason is Reason.OK


def test_a_failed_build_says_why(course, tmp_path):
    (course / "subs" / "ann" / "Makefile").write_text("all:\n\techo broken >&2; exit 2\n")
    built = build_program(BuildStep(course / "subs" / "ann", "make", QUICK), tmp_path / "built")
    assert built.folder is None and built.outcome.reason is Reason.CRASHED and "broken" in built.outcome.stderr_tail


def test_a_program_writes_only_its_own_folders(course):
    outcome = run(
        course,
        """\
        for path in ["/x", "/dev/x", "/usr/x", "/submission/x", "/scene/x", "/out/x", "/tmp/x", "/dev/shm/x", "x"]:
            try:
                open(path, "w").close()
                print("WROTE", path)
            except OSError as exc:
                print("REFUSED", path, exc.strerror)
        write_png(output)
        """,
    )
    assert outcome.reason is Reason.OK
    wrote = {line.split()[1] for line in outcome.stderr_tail.splitlines() if line.startswith("WROTE")}
    assert wrote == {"/tmp/x", "/dev/shm/x", "x"}


def test_a_sandbox_that_cannot_start_stops_the_batch_with_bubblewraps_words(course, monkeypatch):
    folder = Path(tempfile.mkdtemp(prefix="fake-bwrap-"))  # (one the sandbox's user can run a program from)
    folder.chmod(0o755)
    fake = folder / "bwrap"
    fake.write_text("#!/bin/sh\necho 'bwrap: No permissions to create new namespace' >&2\nexit 1\n")
    fake.chmod(0o755)
    monkeypatch.setattr("service.programs.runner.find_bwrap", lambda: str(fake))
    with pytest.raises(SandboxUnavailable, match="cannot start here: bwrap: No permissions"):
        run(course, "write_png(output)\n")
    with pytest.raises(SandboxUnavailable, match="cannot start here"):
        check_sandbox()
    shutil.rmtree(folder)


def test_check_sandbox_passes_where_bubblewrap_works():
    check_sandbox()


def test_a_program_cannot_pass_for_a_sandbox_that_did_not_start(course):
    outcome = run(
        course,
        """\
        print("bwrap: No permissions to create new namespace", file=sys.stderr)
        sys.exit(1)
        """,
    )
    assert outcome.reason is Reason.CRASHED and outcome.detail == "crashed (exit 1)"


def test_a_program_cannot_forge_bubblewraps_failure_past_the_cpu_time_report(course):
    """A program that exits 1 and leaves a child writing bubblewrap's words until the sandbox is torn down pushes
    the shell's report out of the end of standard error: bubblewrap's own status still says it ran.  (How much
    the child writes before the teardown is the scheduler's: the run is made again, up to five times, until the
    report has been pushed out; every run must say the same.)"""
    forged = 0
    for _ in range(5):
        outcome = run(
            course,
            """\
            line = b"bwrap: Creating new namespace failed: Resource temporarily unavailable"
            record = line + b" " * (4095 - len(line)) + b"\\n"
            if os.fork() == 0:
                while True:
                    os.write(2, record)
            sys.exit(1)
            """,
        )
        assert outcome.reason is Reason.CRASHED and outcome.detail == "crashed (exit 1)"
        forged += outcome.stderr_tail.startswith("bwrap: Creating new namespace failed")
        if forged:
            break
    assert forged


@pytest.mark.parametrize(
    ("command", "error"),
    [
        ("python3 'render.py {scene} {output}", "No closing quotation"),
        ("python3 render.py {scene}", "names no {output}"),
        ("", "the command is empty"),
    ],
)
def test_a_command_template_that_cannot_run_is_refused_before_any_run(course, command, error):
    with pytest.raises(ValueError, match=error):
        ProgramRun(course / "subs" / "ann", command, course / "scenes" / "spheres.json")


@pytest.mark.parametrize(("command", "error"), [("make 'all", "No closing quotation"), ("", "the command is empty")])
def test_a_build_command_that_cannot_run_is_refused(course, command, error):
    with pytest.raises(ValueError, match=error):
        BuildStep(course / "subs" / "ann", command)


#: a build that writes into every pipe its parents hold (the stream its folder once came back in) and leaves a
#: daemon writing into them, and into the output file, until the sandbox ends
STREAM_WRITER = """\
import os, sys, time
def spoil():
    mine = os.readlink("/proc/self/fd/2")
    for pid in (os.getppid(), 1):
        try:
            fds = os.listdir(f"/proc/{pid}/fd")
        except OSError:
            continue
        for fd in fds:
            try:
                target = os.readlink(f"/proc/{pid}/fd/{fd}")
                if target.startswith("pipe:") and target != mine:
                    with open(f"/proc/{pid}/fd/{fd}", "wb") as stream:
                        stream.write(b"not a tar stream " * 64)
                    print("SPOILED", pid, fd, file=sys.stderr)
            except OSError as exc:
                print("CANNOT", pid, fd, exc.strerror, file=sys.stderr)
spoil()
if os.fork() == 0:
    os.setpgid(0, 0)
    if os.fork() == 0:
        while True:
            spoil()
            try:
                with open("/out/output.png", "wb") as f:
                    f.write(b"garbage " * 1000)
            except OSError:
                pass
            time.sleep(0.01)
    os._exit(0)
time.sleep(0.3)
"""


def test_a_build_cannot_spoil_the_folder_it_leaves(course, tmp_path):
    """Its result comes back once every other process of the build is gone, in a file none of them could still
    write; the stream of the shell's standard output is the null device."""
    ann = course / "subs" / "ann"
    (ann / "build.py").write_text(STREAM_WRITER)
    (ann / "render.py").write_text(PRELUDE + "write_png(output)\n")
    built = build_program(BuildStep(ann, "python3 build.py", QUICK), tmp_path / "built")
    assert built.outcome.reason is Reason.OK and built.folder is not None, built.outcome
    assert sorted(os.listdir(built.folder)) == ["build.py", "render.py"]
    outcome = run_program(
        ProgramRun(built.folder, "python3 render.py {scene} {output}", course / "scenes" / "spheres.json", QUICK)
    )
    assert outcome.reason is Reason.OK


def test_a_built_folder_that_cannot_be_read_back_is_the_builds_failure(course, tmp_path, monkeypatch):
    """Should a build's result come back as anything but a tar stream, the build failed: never the class."""
    from service.programs import runner

    spoiled = runner.BUILD.replace("exit $s", "echo not a tar stream; echo not a tar stream > /out/output.png; exit $s")
    monkeypatch.setattr(runner, "BUILD", spoiled)
    (course / "subs" / "ann" / "render.py").write_text(PRELUDE + "write_png(output)\n")
    built = build_program(BuildStep(course / "subs" / "ann", "true", QUICK), tmp_path / "built")
    assert built.folder is None and built.outcome.reason is Reason.CRASHED, built.outcome
    assert built.outcome.detail.startswith("its built folder could not be read back")
