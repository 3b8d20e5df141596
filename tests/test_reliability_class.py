"""Class grading tried as a hostile student and a careless TA would (issue 29): untrusted files read safely, one
bad entry never stops the batch, every scene priced first, faults retried with finished work kept, and a report
that is safe to open and to print."""

from __future__ import annotations

import contextlib
import csv
import json
import os
import resource
import shutil
import signal
import socket
import stat
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

import schemas
import tracer
from service import classgrade
from service.classgrade import ClassRun, faults, tasks
from service.classgrade import report as report_module
from service.classgrade.records import GradeJob
from service.classgrade.report import neutral_cell, write_atomic
from service.cli import main
from service.cli.display import printable
from service.render.scenekey import scene_key

from helpers import measured, scene_dict
from server import running_server

SECRET = "hunter2-the-graders-own"


def tiny(name: str = "01_three_spheres", **image) -> dict:
    data = scene_dict(name)
    data["image"].update({"width": 24, "height": 18, **image})
    return data


def right_png(data: dict) -> bytes:
    return tracer.render_png(schemas.validate_scene(json.loads(json.dumps(data))))


def make_class(root: Path, students: dict[str, bytes], data: dict | None = None) -> tuple[Path, Path, bytes]:
    """SCENES/spheres.json and SUBMISSIONS/<student>/spheres.png of each given student; (scenes, subs, right)."""
    data = data or tiny()
    scenes, subs = root / "scenes", root / "subs"
    scenes.mkdir(parents=True)
    subs.mkdir()
    (scenes / "spheres.json").write_text(json.dumps(data))
    right = right_png(data)
    for student, png in students.items():
        (subs / student).mkdir()
        (subs / student / "spheres.png").write_bytes(png or right)
    return scenes, subs, right


def cli(*args: object, timeout: float = 120, env: dict[str, str] | None = None, **popen) -> tuple[int, str, float]:
    """grade-class in a process of its own, as a TA runs it: (exit code, stderr, seconds)."""
    started = time.monotonic()
    proc = subprocess.run(
        [sys.executable, "-m", "service.cli", "grade-class", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=timeout,
        env={**os.environ, **(env or {})},
        errors="backslashreplace",
        **popen,
    )
    return proc.returncode, proc.stderr, time.monotonic() - started


def one_line(err: str) -> str:
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err.removeprefix("phongray: ").strip()


def rows(report: Path) -> dict[str, dict]:
    return {r["student"]: r for r in json.loads((report / "report.json").read_text())}


def everything(report: Path) -> str:
    """Every text the report holds (its files and the names of its files)."""
    out = []
    for path in report.rglob("*"):
        out.append(str(path))
        if path.is_file() and path.suffix in (".json", ".csv", ".html"):
            out.append(path.read_text(errors="replace"))
    return "\n".join(out)


# -- 1 and 2: a hostile class folder, graded once: links, FIFOs, loops, folders, huge files, hostile names ------


@pytest.fixture(scope="module")
def hostile(tmp_path_factory):
    """A class of every hostile entry at once, graded by the CLI in a process of its own (so that a hang is a
    timeout, not a hung suite): (subs, report, exit code, stderr, seconds, the scene's key)."""
    root = tmp_path_factory.mktemp("hostile")
    scenes, subs, right = make_class(root, {"ada": b""})
    report = root / "report"
    key = scene_key(schemas.validate_scene(json.loads((scenes / "spheres.json").read_text())))
    grader = root / "grader"
    grader.mkdir()
    (grader / "secret.json").write_text(json.dumps({"api_key": SECRET, "spheres": SECRET}))

    def folder(name: str) -> Path:
        (subs / name).mkdir()
        return subs / name

    os.symlink("../ada/spheres.png", folder("eve") / "spheres.png")  # someone else's image
    os.symlink(report / "references" / f"{key}.png", folder("refcopy") / "spheres.png")  # the report's reference
    os.symlink("/etc", subs / "etcdir")  # a student folder that is /etc
    os.symlink("/etc", folder("deep") / "hw3")  # a folder one deeper that is /etc
    os.symlink(grader / "secret.json", folder("leak") / "spheres.json")  # a scene that is the grader's JSON
    os.symlink(grader / "secret.json", subs / "leak" / "spheres.PNG.json")
    os.symlink(grader / "secret.json", folder("leak2") / "spheres.png")
    os.mkfifo(folder("fifo") / "spheres.png")  # a plain read blocks forever
    os.mkfifo(folder("fifojson") / "spheres.json")
    os.symlink("spheres.png", folder("loop") / "spheres.png")
    os.symlink("/nonexistent/spheres.png", folder("dangling") / "spheres.png")
    (folder("dirpng") / "spheres.png").mkdir()
    with open(folder("huge") / "spheres.png", "wb") as f:  # 3 GiB, sparse: a few KB on disk
        f.write(right)
        f.truncate(3 << 30)
    for name in ('=HYPERLINK("evil.example","x")', "+1+1", "-2", "@SUM(A1)", "\tx", "\rx"):
        (folder(name) / "spheres.png").write_bytes(right)
    (subs / "\x1b[2J\x1b[Hall 40 students passed.png").write_bytes(b"")  # a loose file, so an ignored line
    code, err, seconds = cli(scenes, subs, "-o", report, "--jobs", "2", timeout=120)
    return subs, report, code, err, seconds, key


def test_the_hostile_class_finishes_with_a_report(hostile):
    subs, report, code, err, seconds, _ = hostile
    assert code == 0, err
    assert (report / "report.json").exists() and (report / "index.html").exists()
    measured("a hostile class: graded in (s)", seconds)  # (bounded by the run's timeout, 120 s)
    assert rows(report)["ada"]["status"] == "pass"


def test_a_link_to_another_students_image_or_the_reports_reference_is_invalid(hostile):
    subs, report, *_ = hostile
    for student in ("eve", "refcopy", "leak2"):
        row = rows(report)[student]
        assert row["status"] == "invalid", row
        assert row["reason"] == f"{subs}/{student}/spheres.png: a symbolic link; links in submissions are not followed"
        assert not (report / "submissions" / student).exists()


def test_a_student_folder_that_links_to_etc_lists_nothing_of_etc(hostile):
    subs, report, _, err, *_ = hostile
    names = set(os.listdir("/etc")) - {"spheres.png"}
    said = everything(report) + err
    for name in ("passwd", "shadow", "hostname", "ssh", "group"):
        if name in names:
            assert f"/{name}" not in said and f"etcdir/{name}" not in said and f"hw3/{name}" not in said
    ignored = [line for line in err.splitlines() if line.startswith("ignored: ")]
    assert f"ignored: {subs}/etcdir: a symbolic link (not followed)" in ignored
    assert "etcdir" not in rows(report)


def test_a_scene_linking_to_a_graders_json_does_not_leak_it(hostile):
    _, report, _, err, *_ = hostile
    assert SECRET not in everything(report) and SECRET not in err
    assert "api_key" not in everything(report)


def test_fifos_loops_dangling_links_and_folders_become_rows_with_their_reason(hostile):
    subs, report, *_ = hostile
    got = rows(report)
    assert got["fifo"]["status"] == "invalid"
    assert got["fifo"]["reason"] == f"{subs}/fifo/spheres.png: a FIFO, not a regular file"
    assert got["fifojson"]["status"] == "missing"  # a scene among the submissions is never opened
    for student in ("loop", "dangling"):
        assert got[student]["reason"] == (
            f"{subs}/{student}/spheres.png: a symbolic link; links in submissions are not followed"
        )
    assert got["dirpng"]["status"] == "invalid"
    assert got["dirpng"]["reason"] == f"{subs}/dirpng/spheres.png: a folder, not a file"


def test_a_3_gib_sparse_submission_is_not_read_nor_copied(hostile):
    subs, report, *_ = hostile
    row = rows(report)["huge"]
    assert row["status"] == "invalid"
    assert row["reason"] == f"{subs}/huge/spheres.png: larger than the limit max_image_bytes = {16 << 20} bytes"
    assert not (report / "submissions" / "huge").exists()


def test_report_csv_cells_that_a_spreadsheet_would_run_are_neutralised(hostile):
    _, report, *_ = hostile
    with open(report / "report.csv", newline="") as f:
        students = [r["student"] for r in csv.DictReader(f)]
    for name in ('=HYPERLINK("evil.example","x")', "+1+1", "-2", "@SUM(A1)", "\tx", "\rx"):
        assert "'" + name in students, (name, students)
    assert not any(s.startswith(report_module.FORMULA_STARTS) for s in students)
    assert rows(report)["-2"]["student"] == "-2"  # report.json keeps the name as it is


def test_names_printed_to_the_terminal_have_their_control_characters_escaped(hostile):
    subs, _, _, err, *_ = hostile
    assert "\x1b" not in err and "\r" not in err
    assert f"ignored: {subs}/\\x1b[2J\\x1b[Hall 40 students passed.png: not in a student's folder" in err.splitlines()
    assert printable("a\x1b[2Jb\nc\u202ed\udcffe\x7f") == "a\\x1b[2Jb\\x0ac\\u202ed\\xffe\\x7f"


def test_neutral_cell_keeps_numbers_and_ordinary_text():
    assert neutral_cell(-1.5) == -1.5 and neutral_cell(None) is None and neutral_cell("ada") == "ada"
    assert [neutral_cell(c + "x") for c in "=+-@\t\r"] == ["'" + c + "x" for c in "=+-@\t\r"]


def test_a_name_of_stray_bytes_does_not_stop_the_report(tmp_path):
    """A folder whose name is not UTF-8 (a tar or zip carries any bytes): its rows, and a report written."""
    scenes, subs, right = make_class(tmp_path, {"ada": b""})
    os.mkdir(os.fsencode(subs) + b"/bad\xff")
    (Path(os.fsdecode(os.fsencode(subs) + b"/bad\xff")) / "spheres.png").write_bytes(right)
    outcome = classgrade.grade_class(ClassRun(scenes, subs, tmp_path / "report", jobs=1))
    assert {r["student"]: r["status"] for r in outcome.rows} == {"ada": "pass", "bad\udcff": "pass"}
    assert rows(tmp_path / "report")["bad\udcff"]["status"] == "pass"  # written as its JSON escape, read back
    assert "bad\\udcff" in (tmp_path / "report" / "report.csv").read_text()
    assert (tmp_path / "report" / "index.html").exists()


@contextlib.contextmanager
def unreadable(*paths: Path):
    """The paths without read permission; as root (which reads everything) the refusal the kernel would give
    anyone else is given by os.scandir and os.open for exactly these paths."""
    for path in paths:
        path.chmod(0)
    if os.geteuid() != 0:
        yield
    else:
        denied = {os.path.abspath(p) for p in paths}
        scandir, open_ = os.scandir, os.open

        def check(path: object, dir_fd: object = None) -> None:
            """(a folder held open, listed or opened in by its descriptor, is named by /proc/self/fd)"""
            if isinstance(path, int):
                path, dir_fd = "", path
            if isinstance(dir_fd, int):
                path = os.path.join(os.readlink(f"/proc/self/fd/{dir_fd}"), os.fsdecode(path))  # type: ignore
            if os.path.abspath(os.fsdecode(path)) in denied:  # type: ignore[arg-type]
                raise PermissionError(13, "Permission denied", os.fsdecode(path))  # type: ignore[arg-type]

        def fake_scandir(path: object = ".") -> object:
            check(path)
            return scandir(path)  # type: ignore[arg-type]

        def fake_open(path: object, *args: object, **kw: object) -> int:
            check(path, kw.get("dir_fd"))
            return open_(path, *args, **kw)  # type: ignore[arg-type]

        os.scandir, os.open = fake_scandir, fake_open  # type: ignore[assignment]
        try:
            yield
        finally:
            os.scandir, os.open = scandir, open_
    for path in paths:
        path.chmod(0o755)


def test_an_unreadable_file_or_folder_is_that_students_row(tmp_path):
    scenes, subs, right = make_class(tmp_path, {"ada": b"", "noread": b"", "nodir": b"", "nosub": b""})
    (subs / "nosub" / "spheres.png").unlink()
    (subs / "nosub" / "hw3").mkdir()
    (subs / "nosub" / "hw3" / "spheres.png").write_bytes(right)
    with unreadable(subs / "noread" / "spheres.png", subs / "nodir", subs / "nosub" / "hw3"):
        outcome = classgrade.grade_class(ClassRun(scenes, subs, tmp_path / "report", jobs=1))
    got = {r["student"]: r for r in outcome.rows}
    assert got["ada"]["status"] == "pass"
    assert got["noread"]["status"] == "invalid"
    assert got["noread"]["reason"] == f"{subs}/noread/spheres.png: cannot read: Permission denied"
    assert got["nodir"]["status"] == "invalid"
    assert got["nodir"]["reason"] == f"{subs}/nodir: cannot read the folder: Permission denied"
    assert got["nosub"]["status"] == "invalid"
    assert got["nosub"]["reason"] == (
        f"no spheres.png found; {subs}/nosub/hw3: cannot read the folder: Permission denied"
    )
    assert (tmp_path / "report" / "report.json").exists()


def test_the_copy_in_the_report_is_the_bytes_that_were_graded(tmp_path):
    """The student's file is replaced once it has been read (before the grade): the copy is what was graded."""
    scenes, subs, right = make_class(tmp_path, {"ada": b""})
    swapped = []

    def swap(done: int, total: int) -> None:
        if not swapped:
            swapped.append(True)
        elif len(swapped) == 1:  # after the submissions are read, before any is graded
            swapped.append(True)
            (subs / "ada" / "spheres.png").write_bytes(b"not the graded bytes")

    outcome = classgrade.grade_class(ClassRun(scenes, subs, tmp_path / "report", jobs=1), progress=swap)
    assert len(swapped) == 2 and outcome.rows[0]["status"] == "pass"
    assert (tmp_path / "report" / "submissions" / "ada" / "spheres.png").read_bytes() == right


# -- 3: every scene priced before anything renders; a render has the service's timeout ---------------------------


def test_a_scene_over_the_cost_limit_stops_the_run_naming_the_file(tmp_path, capsys, monkeypatch):
    scenes, subs, _ = make_class(tmp_path, {"ada": b"", "ben": b""})
    own = tmp_path / "own" / "ada"
    own.mkdir(parents=True)
    (own / "spheres.json").write_text(json.dumps(tiny(samples=2)))
    monkeypatch.setenv("PHONGRAY_MAX_COST", "100")  # the tiny scenes' camera rays alone cost 4.3e2 and 1.7e3
    started = time.monotonic()
    code = main(
        [
            "grade-class",
            str(scenes),
            str(subs),
            "-o",
            str(tmp_path / "r"),
            "--student-scenes",
            str(tmp_path / "own"),
            "--limits",
        ]
    )
    said = one_line(capsys.readouterr().err)
    measured("a class over the cost limit: stopped after (s)", time.monotonic() - started)
    assert code == 2 and time.monotonic() - started < 50  # before any render: a hang, not a slowdown, fails here
    assert said.startswith(f"{own}/spheres.json: image: its camera rays ")  # (the pairs' order: ada's own first)
    assert f"; {scenes}/spheres.json: image: its camera rays " in said and "max_cost = 100 (PHONGRAY_MAX_COST)" in said
    assert not (tmp_path / "r").exists()  # nothing rendered, no report folder left


def test_without_limits_the_tas_scenes_are_trusted(tmp_path, capsys, monkeypatch):
    """Run locally, grade-class grades whatever grade grades: the service's limits apply only with --limits."""
    homework = json.loads((Path(__file__).parents[1] / "examples" / "09_cornell_homework.json").read_text())
    homework["image"].update(width=32, height=24)
    scenes, subs, _ = make_class(tmp_path, {"ada": b""}, data=homework)
    monkeypatch.setenv("PHONGRAY_MAX_COST", "100")
    monkeypatch.setenv("PHONGRAY_RENDER_TIMEOUT", "0")
    code = main(["grade-class", str(scenes), str(subs), "-o", str(tmp_path / "r"), "--jobs", "1"])
    assert code == 0 and rows(tmp_path / "r")["ada"]["status"] == "pass", capsys.readouterr().err


def test_a_render_past_the_services_timeout_stops_the_run_naming_the_file(tmp_path, capsys, monkeypatch):
    scenes, subs, _ = make_class(tmp_path, {"ada": b"x"}, data=tiny("02_all_lights", width=320, height=240, samples=6))
    monkeypatch.setenv("PHONGRAY_RENDER_TIMEOUT", "0.2")  # the render would take several seconds on one core
    monkeypatch.setenv("PHONGRAY_MAX_COST", "1e10")  # (the cost limit, met in the test above, is not this test's)
    started = time.monotonic()
    code = main(["grade-class", str(scenes), str(subs), "-o", str(tmp_path / "r"), "--jobs", "1", "--limits"])
    said = one_line(capsys.readouterr().err)
    measured("a class render past render_timeout = 0.2 s: stopped after (s)", time.monotonic() - started)
    assert code == 2, said
    assert said == (
        f"{scenes}/spheres.json: the render ran past the limit render_timeout = 0.2 s (PHONGRAY_RENDER_TIMEOUT)"
    )


# -- 4: faults retried with backoff, finished work never lost ------------------------------------------------


def killing_grade(job: GradeJob) -> dict:
    """The grade task, in a pool process that is killed (as the OOM killer would) while it grades: once per
    marker of $KILL_ONCE, or always for an image of $KILL_ALWAYS's bytes."""
    marker = os.environ.get("KILL_ONCE")
    if marker and not os.path.exists(marker):
        Path(marker).write_text("killed")
        os.kill(os.getpid(), signal.SIGKILL)
    if job.image == os.environ.get("KILL_ALWAYS", "").encode():
        os.kill(os.getpid(), signal.SIGKILL)
    return tasks.local_grade(job)


def test_a_killed_pool_process_is_retried_and_the_report_is_the_same(tmp_path, monkeypatch):
    scenes, subs, _ = make_class(tmp_path, {"ada": b"", "ben": b""})
    classgrade.grade_class(ClassRun(scenes, subs, tmp_path / "clean", jobs=2))
    monkeypatch.setattr(tasks, "local_grade", killing_grade)
    monkeypatch.setattr(faults, "BACKOFF", 0.01)
    monkeypatch.setenv("KILL_ONCE", str(tmp_path / "killed"))
    outcome = classgrade.grade_class(ClassRun(scenes, subs, tmp_path / "report", jobs=2))
    assert (tmp_path / "killed").exists()  # a pool process was killed
    assert [r["status"] for r in outcome.rows] == ["pass", "pass"]
    assert (tmp_path / "report" / "report.json").read_bytes() == (tmp_path / "clean" / "report.json").read_bytes()


def test_a_pool_process_killed_every_time_stops_with_one_line_and_a_rerun_resumes(tmp_path, capsys, monkeypatch):
    poison = b"poison: its grading is killed every time"
    scenes, subs, _ = make_class(tmp_path, {"ada": b"", "ben": b"", "zed": poison})
    monkeypatch.setattr(tasks, "local_grade", killing_grade)
    monkeypatch.setattr(faults, "BACKOFF", 0.01)
    monkeypatch.setenv("KILL_ALWAYS", poison.decode())
    report = tmp_path / "report"
    started = time.monotonic()
    code = main(["grade-class", str(scenes), str(subs), "-o", str(report), "--jobs", "1"])
    said = one_line(capsys.readouterr().err)
    measured("a pool process killed every time: stopped after (s)", time.monotonic() - started)
    assert code == 2 and time.monotonic() - started < 300  # 5 tries, not forever
    assert said.startswith("the pool of processes: a pool process died (killed, or out of memory) (tried 5 times); ")
    assert said.endswith(f"1 references and 2 grades are kept in {report}: run again to resume")
    kept = {p: p.stat().st_mtime_ns for p in (report / "resume").rglob("*.json")}
    assert {p.parent.name for p in kept} == {"ada", "ben"}
    monkeypatch.delenv("KILL_ALWAYS")
    outcome = classgrade.grade_class(ClassRun(scenes, subs, report, jobs=1))
    assert outcome.renders == 0 and [r["status"] for r in outcome.rows] == ["pass", "pass", "invalid"]
    assert {p: p.stat().st_mtime_ns for p in kept} == kept  # the finished grades were not graded again


def _pool(pid: int) -> list[int]:
    """The processes of the pool of grade-class ``pid``: its descendants that are multiprocessing's (the
    forkserver and the processes forked from it, or spawned ones)."""
    parents: dict[int, tuple[int, bytes]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat_line = Path(f"/proc/{entry}/stat").read_text()
            cmdline = Path(f"/proc/{entry}/cmdline").read_bytes()
        except OSError:
            continue
        parents[int(entry)] = (int(stat_line.rpartition(")")[2].split()[1]), cmdline)
    out: list[int] = []
    for child, (parent, cmdline) in parents.items():
        ancestor = parent
        while ancestor not in (pid, 0, 1) and ancestor in parents:
            ancestor = parents[ancestor][0]
        if ancestor == pid and b"multiprocessing" in cmdline:
            out.append(child)
    return out


def _workers(pid: int) -> list[int]:
    """Those of :func:`_pool` that run tasks: spawned, or forked by the forkserver (not the forkserver itself, nor
    multiprocessing's resource tracker, children of grade-class that run none)."""
    return [p for p in _pool(pid) if _runs_tasks(p, pid)]


def _runs_tasks(child: int, pid: int) -> bool:
    try:
        parent = int(Path(f"/proc/{child}/stat").read_text().rpartition(")")[2].split()[1])
        cmdline = Path(f"/proc/{child}/cmdline").read_bytes()
    except OSError:
        return False
    return b"spawn_main" in cmdline or (parent != pid and b"forkserver" in cmdline)


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[0]
    except OSError:
        return False
    return state != "Z"


@contextlib.contextmanager
def _rendering_class(tmp_path: Path, stderr: int = subprocess.DEVNULL) -> Iterator[tuple[subprocess.Popen, list[int]]]:
    """``grade-class`` of one student at 640×480 (8 s on one core) on two pool processes, its render under way:
    the process, and its pool's (the processes that run tasks, and the forkserver that forked them).  Whatever
    outlives the test is killed by its pid after it."""
    scenes, subs, _ = make_class(tmp_path, {"ada": b""}, data=tiny("02_all_lights", width=640, height=480, samples=2))
    args = [sys.executable, "-m", "service.cli", "grade-class", str(scenes), str(subs), "-o", str(tmp_path / "r")]
    env = {**os.environ, "PHONGRAY_MAX_COST": "1e10"}
    proc = subprocess.Popen(  # (SIGINT as a terminal's Ctrl-C sends it: code run before in this process may have
        [*args, "--jobs", "2"],  # left it ignored, and a signal ignored stays ignored across exec)
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=stderr,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    pool: list[int] = []
    try:
        deadline = time.monotonic() + 30
        while not _workers(proc.pid) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert _workers(proc.pid), "no pool process started"
        pool += _pool(proc.pid)
        time.sleep(0.5)  # the render is under way
        yield proc, pool
    finally:  # (a pool process that outlived grade-class is no longer its child: killed by its pid)
        for pid in {*_pool(proc.pid), *pool, proc.pid}:
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)


def _outlived(pool: list[int], seconds: float) -> bool:
    """Whether some of ``pool`` is still alive ``seconds`` on."""
    deadline = time.monotonic() + seconds
    while any(map(_alive, pool)) and time.monotonic() < deadline:
        time.sleep(0.05)
    return any(map(_alive, pool))


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_pool_processes_die_with_grade_class(tmp_path):
    with _rendering_class(tmp_path) as (proc, pool):
        proc.kill()  # as the OOM killer, or kill -9, would
        proc.wait()
        assert not _outlived(pool, 3), "pool processes outlived grade-class"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_second_ctrl_c_quits_at_once_with_no_traceback(tmp_path):
    """A TA who presses Ctrl-C twice (the first one's exit waits for the pool's render to wind down): exit 130,
    one line, no traceback, no hang; the pool's processes go with it."""
    with _rendering_class(tmp_path, subprocess.PIPE) as (proc, pool):
        proc.send_signal(signal.SIGINT)
        time.sleep(0.2)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
        assert proc.returncode == 130 and err.startswith(b"phongray: interrupted\n"), err
        assert b"Traceback" not in err, err
        assert not _outlived(pool, 10), "pool processes outlived grade-class"


class ResettingProxy:
    """A TCP proxy in front of a server whose connections ``numbers`` (counted from 0) are reset, as a server
    worker that restarts resets its connections, or answered 503 with a Retry-After (``busy``)."""

    def __init__(
        self, target: str, reset: set[int] | None = None, busy: set[int] | None = None, reset_from: int | None = None
    ):
        host, port = target.removeprefix("http://").split(":")
        self.target = (host, int(port))
        self.reset, self.busy, self.reset_from = reset or set(), busy or set(), reset_from
        self.count = 0
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.url = f"http://127.0.0.1:{self.sock.getsockname()[1]}"
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            n, self.count = self.count, self.count + 1
            threading.Thread(target=self._one, args=(conn, n), daemon=True).start()

    def _one(self, conn: socket.socket, n: int) -> None:
        if n in self.reset or (self.reset_from is not None and n >= self.reset_from):
            conn.recv(65536)
            conn.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
            conn.close()  # RST: "connection reset by peer"
            return
        if n in self.busy:
            conn.recv(65536)
            conn.sendall(
                b"HTTP/1.1 503 Service Unavailable\r\nRetry-After: 0\r\nContent-Type: application/json\r\n"
                b'Content-Length: 20\r\nConnection: close\r\n\r\n{"detail": "busy"}  '
            )
            conn.close()
            return
        with conn, socket.create_connection(self.target) as up:

            def pipe(a: socket.socket, b: socket.socket) -> None:
                with contextlib.suppress(OSError):
                    while data := a.recv(65536):
                        b.sendall(data)
                    b.shutdown(socket.SHUT_WR)

            t = threading.Thread(target=pipe, args=(up, conn), daemon=True)
            t.start()
            pipe(conn, up)
            t.join(30)

    def close(self) -> None:
        self.sock.close()


def test_a_server_worker_restart_during_server_is_retried(tmp_path, monkeypatch):
    scenes, subs, _ = make_class(tmp_path, {"ada": b"", "ben": b""})
    classgrade.grade_class(ClassRun(scenes, subs, tmp_path / "local", jobs=1))
    monkeypatch.setattr(faults, "BACKOFF", 0.01)
    with running_server(tmp_path) as (url, _):
        proxy = ResettingProxy(url, reset={2, 3, 5}, busy={6})  # 0, 1: the check (/healthz, /schema)
        try:
            outcome = classgrade.grade_class(ClassRun(scenes, subs, tmp_path / "remote", server=proxy.url, jobs=1))
        finally:
            proxy.close()
    assert proxy.count >= 2 + 1 + 4 + 4  # the check, a render, two requests per grade, the retries
    assert [r["status"] for r in outcome.rows] == ["pass", "pass"]
    assert (tmp_path / "remote" / "report.json").read_bytes() == (tmp_path / "local" / "report.json").read_bytes()


def test_a_server_gone_for_good_stops_with_one_line_and_keeps_what_finished(tmp_path, capsys, monkeypatch):
    scenes, subs, _ = make_class(tmp_path, {"ada": b"", "ben": b""})
    monkeypatch.setattr(faults, "BACKOFF", 0.01)
    report = tmp_path / "report"
    with running_server(tmp_path) as (url, _):
        proxy = ResettingProxy(url, reset_from=2 + 1 + 2)  # the check, the render, ada's grade; then all reset
        try:
            code = main(
                ["grade-class", str(scenes), str(subs), "-o", str(report), "--server", proxy.url, "--jobs", "1"]
            )
        finally:
            proxy.close()
        said = one_line(capsys.readouterr().err)
        assert code == 2
        assert said.startswith(f"--server {proxy.url}: cannot reach {proxy.url}/grade")
        assert "(after 4 retries)" in said and said.endswith(
            f"1 references and 1 grades are kept in {report}: run again to resume"
        )
        outcome = classgrade.grade_class(ClassRun(scenes, subs, report, server=url, jobs=1))  # the rerun resumes
    assert outcome.renders == 0 and [r["status"] for r in outcome.rows] == ["pass", "pass"]


# -- 4: temporary files removed on every error path (a full disk) ---------------------------------------------


@contextlib.contextmanager
def file_size_limit(nbytes: int):
    """Writes past ``nbytes`` fail with EFBIG, as a full disk fails them with ENOSPC: part written, then an
    error."""
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    old = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (nbytes, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
        signal.signal(signal.SIGXFSZ, old)


def test_a_full_disk_leaves_no_partial_temporary_file(tmp_path):
    with file_size_limit(1 << 20), pytest.raises(OSError):
        write_atomic(tmp_path / "ref.png", b"x" * (2 << 20))
    assert os.listdir(tmp_path) == []


def _limit_files() -> None:
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (600, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))


def test_a_full_disk_during_grade_class_is_one_line_and_leaves_no_tmp(tmp_path):
    scenes, subs, _ = make_class(tmp_path, {"ada": b""})
    report = tmp_path / "report"
    code, err, _ = cli(scenes, subs, "-o", report, "--jobs", "1", preexec_fn=_limit_files)
    said = one_line(err)
    assert code == 2 and said.startswith(f"{report}/") and said.endswith(": File too large"), said
    assert [p for p in report.rglob("*") if p.name.endswith(".tmp")] == []


def test_unreadable_helper_restores_permissions(tmp_path):
    (tmp_path / "f").write_text("x")
    with unreadable(tmp_path / "f"):
        with pytest.raises(PermissionError):
            os.open(tmp_path / "f", os.O_RDONLY)
    assert stat.S_IMODE((tmp_path / "f").stat().st_mode) == 0o755


def _start(args: list[str], log: Path) -> subprocess.Popen:
    with open(log, "w") as out:
        return subprocess.Popen(args, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def test_a_lost_dask_scheduler_is_retried_then_stops_with_one_line_keeping_what_finished(tmp_path, capsys, monkeypatch):
    pytest.importorskip("distributed")
    from server import free_port

    scenes, subs, right = make_class(tmp_path, {"ada": b""})
    slow = tiny("03_soft_shadows", width=400, height=400, samples=2)  # about 3 s on a worker thread
    (scenes / "lamps.json").write_text(json.dumps(slow))
    (subs / "ada" / "lamps.png").write_bytes(right)
    key = scene_key(schemas.validate_scene(json.loads((scenes / "spheres.json").read_text())))
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    scheduler = _start(
        [
            sys.executable,
            "-m",
            "distributed.cli.dask_scheduler",
            "--host",
            "127.0.0.1",
            "--port",
            str(port),
            "--dashboard-address",
            "127.0.0.1:0",
        ],
        tmp_path / "scheduler.log",
    )
    worker = _start(
        [
            sys.executable,
            "-m",
            "distributed.cli.dask_worker",
            address,
            "--nthreads",
            "2",
            "--no-nanny",
            "--host",
            "127.0.0.1",
        ],
        tmp_path / "worker.log",
    )
    report = tmp_path / "report"

    def lose_the_scheduler() -> None:  # once the quick reference is in, while the slow one renders
        deadline = time.monotonic() + 60
        while not (report / "references" / f"{key}.png").exists() and time.monotonic() < deadline:
            time.sleep(0.02)
        _stop(scheduler)

    monkeypatch.setattr(faults, "BACKOFF", 0.01)
    monkeypatch.setattr(faults, "RECONNECT_TIMEOUT", 0.5)
    killer = threading.Thread(target=lose_the_scheduler, daemon=True)
    try:
        killer.start()
        started = time.monotonic()
        code = main(["grade-class", str(scenes), str(subs), "-o", str(report), "--cluster", address])
        seconds = time.monotonic() - started
    finally:
        _stop(scheduler)
        _stop(worker)
    said = one_line(capsys.readouterr().err)
    measured("a class whose scheduler is lost: stopped after (s)", seconds)
    assert code == 2 and seconds < 300, said  # 5 tries, not forever
    assert said.startswith(f"--cluster {address}: cannot reach the Dask scheduler at {address}")
    assert "(tried 5 times); stopped with 1 tasks unfinished; " in said
    assert said.endswith(f"1 references and 0 grades are kept in {report}: run again to resume")
    assert (report / "references" / f"{key}.png").exists()


# -- 4: a rerun trusts nothing it did not write: resume journals, and names shown as they are -------------------


def test_a_resume_row_tampered_with_or_of_another_version_is_graded_again(tmp_path):
    from service.classgrade import journal

    black = tracer.encode_png(tracer.render(schemas.validate_scene({**tiny(), "objects": [], "lights": []})))
    scenes, subs, _ = make_class(tmp_path, {"ada": b"", "bob": black, "cy": b"", "dee": b""})
    report = tmp_path / "report"
    classgrade.grade_class(ClassRun(scenes, subs, report, jobs=1))
    before = (report / "report.json").read_bytes()
    files = {s: report / "resume" / s / "spheres.json" for s in ("ada", "bob", "cy", "dee")}
    kept = {s: json.loads(p.read_text()) for s, p in files.items()}
    assert {k["stamp"]["phongray"] for k in kept.values()} == {journal.version()}
    assert {k["stamp"]["format"] for k in kept.values()} == {journal.FORMAT}
    assert kept["bob"]["row"]["status"] == "fail"
    tampered = {  # a status no report knows, a number that is text, a list in a list, another version
        "ada": {**kept["ada"], "row": {**kept["ada"]["row"], "status": "<script>alert(1)</script>"}},
        "cy": {**kept["cy"], "row": {**kept["cy"]["row"], "fraction_off_nearby": "x"}},
        "bob": {**kept["bob"], "row": {**kept["bob"]["row"], "mistakes": [["no-shadows"]]}},
        "dee": {
            "stamp": {**kept["dee"]["stamp"], "phongray": "0.0.1"},
            "row": {**kept["dee"]["row"], "status": "fail", "passed": False},
        },
    }
    for student, data in tampered.items():
        files[student].write_text(json.dumps(data))
    outcome = classgrade.grade_class(ClassRun(scenes, subs, report, jobs=1))
    assert (report / "report.json").read_bytes() == before  # each graded again, as it was
    assert [r["status"] for r in outcome.rows] == ["pass", "fail", "pass", "pass"]
    assert "<script>" not in (report / "index.html").read_text()
    assert {s: json.loads(p.read_text()) for s, p in files.items()} == kept


def test_a_resume_journal_that_is_a_fifo_dev_zero_or_huge_is_graded_again_not_waited_on(tmp_path):
    scenes, subs, _ = make_class(tmp_path, {"ada": b"", "bob": b"", "cy": b""})
    report = tmp_path / "report"
    assert cli(scenes, subs, "-o", report, "--jobs", "1")[0] == 0

    def kept(student: str) -> Path:
        return report / "resume" / student / "spheres.json"

    kept("ada").unlink()
    os.mkfifo(kept("ada"))  # a plain read waits for a writer forever
    kept("bob").unlink()
    os.symlink("/dev/zero", kept("bob"))  # a plain read never ends
    with open(kept("cy"), "ab") as f:
        f.write(b" " * (4 << 20))  # still JSON, larger than any journal
    code, err, _ = cli(scenes, subs, "-o", report, "--jobs", "1", timeout=60)
    assert code == 0, err
    assert {s: r["status"] for s, r in rows(report).items()} == {"ada": "pass", "bob": "pass", "cy": "pass"}
    for student in ("ada", "bob", "cy"):  # graded again, and kept anew
        assert stat.S_ISREG(os.lstat(kept(student)).st_mode) and kept(student).stat().st_size < 4096


BIDI = "\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069\u200e\u200f"


def test_bidirectional_controls_in_names_are_shown_escaped(tmp_path):
    """A name that would reorder what is around it ('ada<RLO>gnp.exe' shows as 'adaexe.png') is shown escaped in
    index.html and the CSV files; report.json keeps it as it is."""
    name = "ada" + "".join(f"{c}{i}" for i, c in enumerate(BIDI))
    scenes, subs, _ = make_class(tmp_path, {name: b"", "bob": b""})
    (subs / name / "notes.png").write_bytes(b"")  # an ignored file of theirs, listed in the HTML
    report = tmp_path / "report"
    classgrade.grade_class(ClassRun(scenes, subs, report, jobs=1))
    shown = "ada" + "".join(f"\\u{ord(c):04x}{i}" for i, c in enumerate(BIDI))
    for file in ("index.html", "report.csv", "gradebook.csv"):
        text = (report / file).read_text()
        assert not set(BIDI) & set(text), file
        assert shown in text, file
    assert f"{shown}/notes.png: matches no task" in (report / "index.html").read_text()
    assert rows(report)[name]["status"] == "pass"


def test_no_two_pairs_of_the_html_report_share_an_anchor(tmp_path):
    """Student 'ada' and task 'x-spheres', student 'ada-x' and task 'spheres': each cell opens its own pair."""
    import re

    scenes, subs, right = make_class(tmp_path, {"ada": b"", "ada-x": b""})
    (scenes / "x-spheres.json").write_text((scenes / "spheres.json").read_text())
    (subs / "ada" / "x-spheres.png").write_bytes(right)
    report = tmp_path / "report"
    classgrade.grade_class(ClassRun(scenes, subs, report, jobs=1))
    page = (report / "index.html").read_text()
    ids = re.findall(r'<section class="pair" id="([^"]+)"', page)
    assert len(ids) == 4 == len(set(ids)), ids
    assert sorted(re.findall(r'<td class="[^"]*"><a href="#([^"]+)"', page)) == sorted(ids)


def test_a_rerun_into_the_same_report_leaves_no_results_of_a_student_not_in_it(tmp_path):
    """The TA graded the wrong folder (or a student's name changed) and runs again into the same report: no
    results.json of a student of the first run is left in gradescope/ to be uploaded with this class's."""
    scenes, subs, right = make_class(tmp_path, {"ada": b"", "bob": b""})
    report = tmp_path / "report"
    classgrade.grade_class(ClassRun(scenes, subs, report, jobs=1))
    (report / "gradescope" / "notes.txt").write_text("the TA's own")
    (subs / "bob").rename(subs / "Bob Brown_7_assignsubmission_file_")
    classgrade.grade_class(ClassRun(scenes, subs, report, jobs=1))
    assert sorted(os.listdir(report / "gradescope")) == ["Bob Brown", "ada", "notes.txt"]
    assert json.loads((report / "gradescope" / "Bob Brown" / "results.json").read_text())["score"] == 1.0


def test_a_folder_of_thousands_of_resubmissions_gives_a_short_reason(tmp_path):
    """Every one of 3000 spheres-N.png is a candidate: the reason names a few, not 3000 paths in every file of
    the report (and every Gradescope output)."""
    scenes, subs, right = make_class(tmp_path, {"ada": b"", "bob": b""})
    (subs / "bob" / "spheres.png").unlink()
    for n in range(3000):
        (subs / "bob" / f"spheres-{n}.png").write_bytes(b"")
        (subs / "bob" / f"sphere-{n}.png").write_bytes(b"")
    report = tmp_path / "report"
    classgrade.grade_class(ClassRun(scenes, subs, report, jobs=1))
    reason = rows(report)["bob"]["reason"]
    assert reason.startswith("3000 files for spheres: ") and reason.endswith(" and 2995 more; keep one")
    assert len(reason) < 1000 and (report / "index.html").stat().st_size < 1_000_000
    (subs / "bob" / "spheres-0.png").unlink()
    for n in range(1, 3000):
        (subs / "bob" / f"spheres-{n}.png").unlink()
    classgrade.grade_class(ClassRun(scenes, subs, report, jobs=1))
    reason = rows(report)["bob"]["reason"]
    assert (
        reason.startswith("no spheres.png (found sphere-")
        and reason.endswith(" and 2995 more: did you mean spheres.png?)")
        and len(reason) < 1000
    )


@pytest.mark.parametrize(
    "broken",
    [
        lambda png: png[:100],  # cut short (a copy that failed)
        lambda png: b"version https://git-lfs.github.com/spec/v1\noid sha256:0\nsize 1\n",  # a Git LFS pointer
    ],
)
def test_a_kept_reference_that_does_not_decode_is_rendered_again(tmp_path, broken):
    scenes, subs, right = make_class(tmp_path, {"ada": b"", "bob": b""})
    report = tmp_path / "report"
    classgrade.grade_class(ClassRun(scenes, subs, report, jobs=1))
    (ref,) = (report / "references").iterdir()
    ref.write_bytes(broken(ref.read_bytes()))
    shutil.rmtree(report / "resume")
    outcome = classgrade.grade_class(ClassRun(scenes, subs, report, jobs=1))
    assert outcome.renders == 1 and [r["status"] for r in outcome.rows] == ["pass", "pass"]
    assert ref.read_bytes() == right


def test_a_name_of_255_bytes_that_composing_would_lengthen_is_graded(tmp_path):
    """NFC decomposes U+0958: 85 of them (255 bytes) would be 510 bytes, no file name of the report's."""
    name = "\u0958" * 85
    scenes, subs, _ = make_class(tmp_path, {name: b"", "bob": b""})
    outcome = classgrade.grade_class(ClassRun(scenes, subs, tmp_path / "report", jobs=1))
    assert [(r["student"], r["status"]) for r in outcome.rows] == [("bob", "pass"), (name, "pass")]
