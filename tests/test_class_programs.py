"""A class of students' programs graded in one command (grade-class --run): honest ones pass, buggy ones fail
with their mistakes named (by experiment where the image alone cannot), hostile ones are contained, each pair
with its reason, nothing leaked or left running; a hidden task shows a student only what tasks.json says.

Every program is tests/programs/tracer.py (the system's python3, the standard library only), a buggy one with a
mistake switched on, a hostile one with a few lines before it that misbehave on the task ``glass`` only."""

import json
import os
import shutil
import socket
import sys
import tempfile
import threading
import time
from pathlib import Path

import pytest
from test_cluster import DASK, _start, _stop, _workers

from service.classgrade import journal
from service.classgrade.feedback import ZEROED
from service.cli import main
from service.programs import check_sandbox

from helpers import left_in_sandboxes
from server import free_port

HERE = Path(__file__).parent / "programs"
SECRET = "TA-SECRET-51c0"
RUN = "python3 tracer.py {scene} {output}"
#: short limits, so that a hostile program is stopped in seconds
LIMITS = ["--run-timeout", "4", "--memory", "512M", "--processes", "32", "--output-size", "8M"]

#: the few lines each hostile program starts with (``{scenes}``, ``{other}``, ``{port}``: filled in)
HOSTILE = {
    "loop": 'import sys\nwhile "glass" in sys.argv[1]:\n    pass\n',
    "forkbomb": 'import os, sys\nwhile "glass" in sys.argv[1]:\n    try:\n        os.fork()\n    except OSError:\n'
    "        pass\n",
    "hog": 'import sys\nif "glass" in sys.argv[1]:\n    hoard = []\n    while True:\n'
    "        hoard.append(bytearray(16 << 20))\n",
    "bigfile": 'import sys\nif "glass" in sys.argv[1]:\n    with open("big", "wb") as f:\n'
    '        for _ in range(5 * 1024):\n            f.write(b"x" * (1 << 20))\n',
    "link": 'import os, sys\nif "glass" in sys.argv[1]:\n    try:\n        os.remove(sys.argv[2])\n'
    '        os.symlink("/etc/passwd", sys.argv[2])\n    except OSError as exc:\n'
    '        print("refused", exc, file=sys.stderr)\n    sys.exit(0)\n',
    "snoop": 'import sys\nfor path in ("{scenes}/spot.json", "{scenes}/notes.txt", "{other}/tracer.py",\n'
    '             "{other}/mistakes.txt"):\n    try:\n'
    '        print("LEAK", open(path).read(), file=sys.stderr)\n'
    '    except OSError as exc:\n        print("refused", exc, file=sys.stderr)\n',
    "network": 'import socket, sys\ntry:\n    socket.create_connection(("127.0.0.1", {port}), timeout=2)\n'
    '    print("LEAK connected", file=sys.stderr)\nexcept OSError as exc:\n'
    '    print("refused", exc, file=sys.stderr)\n',
    "daemon": "import os\nif os.fork() == 0:\n    os.setsid()\n    if os.fork() == 0:\n"
    '        os.execvp("sleep", ["sleep", "876.543"])\n    os._exit(0)\nos.wait()\n',
    # four children of 140 MB each: each within the 512 MiB limit, together over it (the memory they touch
    # before the kill is about the hog's)
    "fourkids": 'import os, sys, time\nif "glass" in sys.argv[1]:\n    kids = []\n    for _ in range(4):\n'
    "        pid = os.fork()\n        if pid == 0:\n            block = bytearray(140 << 20)\n"
    "            for i in range(0, len(block), 4096):\n                block[i] = 1\n"
    "            time.sleep(30)\n            os._exit(0)\n        kids.append(pid)\n    for pid in kids:\n"
    "        os.waitpid(pid, 0)\n",
    # every process its limit allows, held until the run is killed (beside another student's run: --jobs 2)
    "quota": 'import os, sys, time\nif "glass" in sys.argv[1]:\n    try:\n        while True:\n'
    "            if os.fork() == 0:\n                time.sleep(30)\n                os._exit(0)\n"
    "    except OSError:\n        pass\n    time.sleep(30)\n",
}
BUGGY = {"noshadow": "no-shadows", "hardspot": "spot-hard-edge", "noglass": "no-refraction"}
#: programs that fail the task (no shadows) and answer a scene of one light (a probe's) with what is not its
#: image: bytes that are no PNG, or a 20000² PNG of a few tens of kilobytes
PROBING = {
    "garbage": 'import json, sys\nif len(json.load(open(sys.argv[1]))["lights"]) == 1:\n'
    '    open(sys.argv[2], "wb").write(b"no PNG here")\n    sys.exit(0)\n',
    "bomb": 'import json, struct, sys, zlib\nif len(json.load(open(sys.argv[1]))["lights"]) == 1:\n'
    "    def chunk(kind, body):\n"
    '        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))\n'
    '    head = struct.pack(">IIBBBBB", 20000, 20000, 1, 0, 0, 0, 0)\n'
    '    body = zlib.compress(b"\\0" * 2501 * 20000, 9)\n'
    '    png = b"\\x89PNG\\r\\n\\x1a\\n" + chunk(b"IHDR", head) + chunk(b"IDAT", body) + chunk(b"IEND", b"")\n'
    '    open(sys.argv[2], "wb").write(png)\n    sys.exit(0)\n',
}


def left_running() -> list[str]:
    """What this test's runs left running: a sandbox or anything under it, or the hostile daemon's sleep;
    zombies do not count."""
    return left_in_sandboxes("876.543")


def scratch() -> set[str]:
    """The temporary folders of runs, builds and scenes of this process's tests (tests/conftest.py gives it a
    temporary folder of its own)."""
    return {p.name for p in Path(tempfile.gettempdir()).glob("phongray-*")}


def make_class(root: Path, port: int, students: list[str]) -> tuple[Path, Path]:
    scenes, subs = root / "scenes", root / "subs"
    scenes.mkdir()
    for task in ("spot", "glass"):
        (scenes / f"{task}.json").write_text((HERE / f"{task}.json").read_text())
    (scenes / "notes.txt").write_text(SECRET)
    (root / "tasks.json").write_text(json.dumps({"spot": {"show": "images"}, "glass": {"show": "verdict-only"}}))
    tracer = (HERE / "tracer.py").read_text()
    for student in students:
        folder = subs / student
        folder.mkdir(parents=True)
        prefix = HOSTILE.get(student, "").format(scenes=scenes, other=subs / "honest", port=port)
        (folder / "tracer.py").write_text(PROBING.get(student, "") + prefix + tracer)
        mistakes = "no-shadows" if student in PROBING else BUGGY.get(student, "")
        (folder / "mistakes.txt").write_text(mistakes + f"\n# {SECRET}\n")
    return scenes, subs


@pytest.fixture
def listener():
    """A TCP listener on the machine's loopback, and what connected to it."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()
    server.settimeout(0.2)
    accepted: list[object] = []
    stop = threading.Event()

    def accept() -> None:
        while not stop.is_set():
            try:
                accepted.append(server.accept())
            except OSError:
                pass

    thread = threading.Thread(target=accept, daemon=True)
    thread.start()
    yield server.getsockname()[1], accepted
    stop.set()
    thread.join()
    server.close()


def grade(root: Path, scenes: Path, subs: Path, *more: str) -> tuple[int, dict, str]:
    report = root / "report"
    code = main(
        [
            "grade-class",
            str(scenes),
            str(subs),
            "-o",
            str(report),
            "--tasks",
            str(root / "tasks.json"),
            "--run",
            RUN,
            *LIMITS,
            *more,
        ]
    )
    rows = json.loads((report / "report.json").read_text()) if code == 0 else []
    return code, {(r["student"], r["task"]): r for r in rows}, report


def test_a_class_of_honest_buggy_and_hostile_programs(tmp_path, listener, capsys):
    check_sandbox()
    port, accepted = listener
    students = ["honest", *BUGGY, *HOSTILE]
    scenes, subs = make_class(tmp_path, port, students)
    before = scratch()
    code, rows, report = grade(tmp_path, scenes, subs, "--jobs", "2")
    assert code == 0, capsys.readouterr().err
    summary = capsys.readouterr().out
    assert "28 pairs: 17 passed, 11 failed, 0 missing, 0 invalid" in summary
    assert "students' programs ran here: each run's memory is held by" in summary  # (which way: the machine's)

    assert rows["honest", "spot"]["status"] == rows["honest", "glass"]["status"] == "pass"
    assert rows["noshadow", "spot"]["status"] == "fail" and "no-shadows" in rows["noshadow", "spot"]["mistakes"]
    hard = rows["hardspot", "spot"]
    assert hard["status"] == "fail"
    assert hard["likely"] == "your spot light 'key' is wrong between its inner and outer cone"
    assert rows["noglass", "glass"]["experiment"] == "reflection right, refraction missing"
    assert rows["noglass", "spot"]["status"] == "pass"

    reasons = {
        "loop": ("timeout",),
        "forkbomb": ("timeout", "crashed"),
        "hog": ("memory",),
        "fourkids": ("memory",),
        "quota": ("timeout",),
        "bigfile": ("output-too-large",),
        "link": ("no-output",),
    }
    for student, expected in reasons.items():
        row = rows[student, "glass"]
        assert row["status"] == "fail" and row["run"] in expected, (student, row["run"], row["reason"])
        assert row["reason"].startswith("the run failed: ")
        assert rows[student, "spot"]["status"] == "pass"  # the batch went on, and so did the student's tasks
    for student in ("snoop", "network", "daemon"):
        assert {rows[student, t]["status"] for t in ("spot", "glass")} == {"pass"}
    assert "refused" in rows["snoop", "spot"]["run_output"] and "refused" in rows["network", "spot"]["run_output"]

    everything = "".join(
        p.read_text(errors="replace")
        for p in report.rglob("*")
        if p.is_file() and p.suffix in (".json", ".csv", ".html")
    )
    assert "LEAK" not in everything and SECRET not in everything
    assert "refused" in (report / "index.html").read_text()  # the TA's page shows a run's output
    assert not any("refused" in p.read_text() for p in (report / "gradescope").rglob("*.json"))  # a student's never
    assert accepted == []
    assert left_running() == []
    assert scratch() <= before  # nothing of a run left on the disk


def test_a_hidden_task_shows_a_student_only_what_tasks_json_says(tmp_path, listener):
    check_sandbox()
    scenes, subs = make_class(tmp_path, listener[0], ["honest", "noglass", "hardspot"])
    code, rows, report = grade(tmp_path, scenes, subs)
    assert code == 0
    results = json.loads((report / "gradescope" / "noglass" / "results.json").read_text())
    tests = {t["name"]: t for t in results["tests"]}
    assert tests["glass"]["output"] == "failed"  # verdict only: no reason, no diagnosis
    spot = json.loads((report / "gradescope" / "hardspot" / "results.json").read_text())
    assert "between its inner and outer cone" in {t["name"]: t for t in spot["tests"]}["spot"]["output"]
    scene_text = (scenes / "glass.json").read_text()
    for path in report.rglob("*"):
        assert path.suffix != ".json" or path.read_text() != scene_text
        assert '"look_at"' not in (path.read_text(errors="replace") if path.is_file() else "")


def test_a_hidden_scenes_run_is_told_to_a_student_without_its_exit_status(tmp_path, listener):
    """Under ``show: verdict`` a program that exits 43 on the hidden scene is told "crashed": its exit status
    could carry 8 bits of the scene.  The TA's report keeps the status."""
    check_sandbox()
    scenes, subs = make_class(tmp_path, listener[0], ["exit43"])
    (subs / "exit43" / "tracer.py").write_text('import sys\nif "glass" in sys.argv[1]:\n    sys.exit(43)\n')
    (tmp_path / "tasks.json").write_text(json.dumps({"glass": {"show": "verdict"}}))
    code, rows, report = grade(tmp_path, scenes, subs)
    assert code == 0 and rows["exit43", "glass"]["reason"] == "the run failed: crashed: crashed (exit 43)"
    results = json.loads((report / "gradescope" / "exit43" / "results.json").read_text())
    assert {t["name"]: t["output"] for t in results["tests"]}["glass"] == "fail: the run failed: crashed"
    assert "43" not in json.dumps(results)


def test_a_programs_image_that_is_no_image_is_invalid_as_its_own_with_its_run_kept(tmp_path, listener):
    """A program that writes what is no image: its pair is invalid, said of the program's image (never by the
    TA's folder, which a student must not see), and the TA keeps what the run printed."""
    check_sandbox()
    scenes, subs = make_class(tmp_path, listener[0], ["junk"])
    (subs / "junk" / "tracer.py").write_text(
        'import sys\nprint("Rendering...", file=sys.stderr)\nopen(sys.argv[2], "wb").write(b"no image")\n'
    )
    code, rows, report = grade(tmp_path, scenes, subs)
    row = rows["junk", "spot"]
    assert code == 0 and row["status"] == "invalid", row
    assert row["reason"] == "the program's image: image is not a PNG or a PPM; PNG or PPM required", row
    assert row["run"] == "ok" and "Rendering..." in row["run_output"], row
    results = (report / "gradescope" / "junk" / "results.json").read_text()
    assert str(tmp_path) not in results and "the program's image" in results
    kept = json.loads(journal.path(report, "junk", "spot").read_text())  # (kept for a run that resumes)
    assert journal.valid_row(kept["row"]) and kept["row"]["run"] == "ok", kept


def test_a_probe_answered_with_no_image_is_that_probes_no_answer_and_the_class_is_graded(tmp_path, listener):
    """A program that fails its task and answers the one-light probes with bytes that are no PNG, or with a
    20000² PNG, is asked the others; its pair fails with its mistake named, and every student is graded."""
    check_sandbox()
    scenes, subs = make_class(tmp_path, listener[0], ["honest", "garbage", "bomb"])
    code, rows, report = grade(tmp_path, scenes, subs, "--jobs", "2")
    assert code == 0
    for student in ("garbage", "bomb"):
        row = rows[student, "spot"]
        assert row["status"] == "fail" and "no-shadows" in row["mistakes"]
        assert "the program's image could not be read (not a PNG of its size)" in row["experiment"]
    assert rows["honest", "spot"]["status"] == rows["honest", "glass"]["status"] == "pass"
    assert (report / "gradescope" / "bomb" / "results.json").exists()


def test_a_program_holding_phongray_is_flagged_and_scored_as_tasks_json_says(tmp_path, listener):
    """phongray's code in a student's folder (here beside the honest tracer it runs) is flagged for the TA:
    the spot task scores nothing for it (``"phongray_code": "zero"``, and the student reads why), the glass
    task keeps its grade (``review``).  An honest program whose images are the references byte for byte is
    flagged for review only: its score stands and the student reads nothing of it."""
    check_sandbox()
    scenes, subs = make_class(tmp_path, listener[0], ["honest", "vendor"])
    root = Path(__file__).parent.parent
    for package in ("tracer", "schemas"):
        shutil.copytree(root / package, subs / "vendor" / package, ignore=shutil.ignore_patterns("__pycache__"))
    (tmp_path / "tasks.json").write_text(json.dumps({"spot": {"phongray_code": "zero"}}))
    code, rows, report = grade(tmp_path, scenes, subs)
    assert code == 0
    spot, glass = rows["vendor", "spot"], rows["vendor", "glass"]
    assert spot["status"] == glass["status"] == "pass" and spot["flag"] == glass["flag"] == "phongray-code"
    assert "lines of phongray's own code" in spot["flag_reason"]
    assert (spot["score"], glass["score"]) == (0, 1)
    tests = {t["name"]: t for t in json.loads((report / "gradescope" / "vendor" / "results.json").read_text())["tests"]}
    assert tests["spot"]["output"].endswith(ZEROED) and "phongray" not in tests["glass"]["output"]
    assert tests["glass"]["extra_data"]["flag"] == "phongray-code"
    honest = rows["honest", "spot"]
    assert honest["flag"] == "identical" and honest["score"] == 1
    assert "phongray" not in json.dumps(
        [t["output"] for t in json.loads((report / "gradescope" / "honest" / "results.json").read_text())["tests"]]
    )
    assert "4 flagged for review" in (report / "index.html").read_text()


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--run", "python3 tracer.py {scene}"], "names no {output}"),
        (["--run", "python3 tracer.py {output}"], "names no {scene}"),
        (["--run", RUN, "--build", "mkae"], "no program 'mkae'"),
        (["--build", "make"], "--build: only with --run"),
    ],
)
def test_a_tas_mistake_is_exit_2_and_one_line_and_no_student_is_marked(tmp_path, listener, capsys, args, words):
    scenes, subs = make_class(tmp_path, listener[0], ["honest"])
    code = main(["grade-class", str(scenes), str(subs), "-o", str(tmp_path / "report"), *args])
    err = capsys.readouterr().err
    assert code == 2 and words in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "report").exists()


def test_without_bubblewrap_a_class_stops_unless_asked_to_run_unsandboxed(tmp_path, listener, capsys, monkeypatch):
    scenes, subs = make_class(tmp_path, listener[0], ["honest"])
    monkeypatch.setattr("shutil.which", lambda name, *a, **k: None if name == "bwrap" else f"/usr/bin/{name}")
    code = main(["grade-class", str(scenes), str(subs), "-o", str(tmp_path / "report"), "--run", RUN])
    err = capsys.readouterr().err
    assert code == 2 and "bubblewrap (bwrap) is not installed" in err and len(err.strip().splitlines()) == 1
    monkeypatch.undo()
    code, rows, _ = grade(tmp_path, scenes, subs, "--no-sandbox")
    assert code == 0 and rows["honest", "spot"]["status"] == "pass"
    assert capsys.readouterr().err.count("WARNING: run without a sandbox") == 2  # one for each run


def test_a_sandbox_that_stops_starting_mid_batch_is_the_tas_one_line(tmp_path, listener, capsys, monkeypatch):
    """The batch's check started a sandbox; then a student's does not start (a limit on processes reached):
    exit 2 and one line naming the cause, never a traceback, and no student marked for it."""
    check_sandbox()
    scenes, subs = make_class(tmp_path, listener[0], ["honest"])
    fake = Path(tempfile.mkdtemp(prefix="fake-bwrap-"))
    fake.chmod(0o755)  # (a run's user runs it)
    (fake / "bwrap").write_text(
        '#!/bin/sh\ncase "$*" in *tracer.py*)\n'
        "  echo 'bwrap: Creating new namespace failed: Resource temporarily unavailable' >&2; exit 1;;\nesac\n"
        f'exec {shutil.which("bwrap")} "$@"\n'
    )
    (fake / "bwrap").chmod(0o755)
    monkeypatch.setenv("PATH", f"{fake}:{os.environ['PATH']}")
    code, _, report = grade(tmp_path, scenes, subs, "--jobs", "1")
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert "honest's program: the sandbox cannot start here: bwrap: Creating new namespace failed" in err
    assert "a limit on processes was reached: the grading user's (ulimit -u" in err
    assert not list(report.glob("gradescope/*/results.json"))


@pytest.fixture
def blind_cluster():
    """A scheduler and two workers on 127.0.0.1 that share no folder with this session: each worker sees the
    machine through bubblewrap with this session's temporary folder (every test's files) an empty one of its
    own, and works in another folder, as a worker on another machine would."""
    view = Path(tempfile.mkdtemp(prefix="view-")) / "worker-view"  # (bwrap by another name: no student's sandbox)
    view.symlink_to(shutil.which("bwrap") or "bwrap")
    hidden = ["--dev-bind", "/", "/", "--tmpfs", tempfile.gettempdir(), "--chdir", "/", "--"]
    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    logs = Path(tempfile.mkdtemp(prefix="blind-dask-"))
    scheduler = [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", str(port)]
    procs = [_start([*scheduler, "--dashboard-address", "127.0.0.1:0"], logs / "scheduler.log")]
    try:
        for k in range(2):
            worker = [*DASK, address, "--nthreads", "1", "--no-nanny", "--host", "127.0.0.1", "--name", f"w{k}"]
            procs.append(_start([str(view), *hidden, *worker, "--dashboard-address", "127.0.0.1:0"], logs / f"w{k}"))
        deadline = time.monotonic() + 60
        while _ready(address) < 2:
            if time.monotonic() > deadline or any(p.poll() is not None for p in procs):
                raise RuntimeError("the Dask cluster did not start: " + (logs / "w0").read_text()[-2000:])
            time.sleep(0.3)
        yield address
    finally:
        for proc in reversed(procs):
            _stop(proc)


def _ready(address: str) -> int:
    try:
        return _workers(address)
    except OSError:
        return 0


def test_the_same_class_on_a_cluster_that_shares_no_folder(tmp_path, listener, blind_cluster, monkeypatch):
    """Each student's program a task of a worker's, its folder sent as bytes: from a relative submissions path,
    to workers that cannot see it, the same report as here (each run in its own sandbox there)."""
    check_sandbox()
    students = ["honest", "noglass", "loop", "link", "fourkids", "quota", "garbage"]
    scenes, subs = make_class(tmp_path, listener[0], students)
    monkeypatch.chdir(tmp_path)
    # (a wall time of 10 s, not 4: beside another file's Dask cluster in CI, the four children's 560 MB was not
    # all touched within 4 s on the workers, and the same run must end the same way here and there)
    limits = [
        *LIMITS[: LIMITS.index("--run-timeout")],
        "--run-timeout",
        "10",
        *LIMITS[LIMITS.index("--run-timeout") + 2 :],
    ]
    for report, more in (("here", []), ("there", ["--cluster", blind_cluster])):
        args = ["grade-class", "scenes", "subs", "-o", report, "--tasks", "tasks.json", "--run", RUN, *limits]
        assert main([*args, "--jobs", "2", "-q", *more]) == 0

    def rows(report: str) -> list[dict]:
        return [
            {k: v for k, v in r.items() if k != "run_seconds"}
            for r in json.loads((tmp_path / report / "report.json").read_text())
        ]

    differing = [
        (there["student"], there["task"], key, there[key], here.get(key))
        for there, here in zip(rows("there"), rows("here"), strict=True)
        for key in there
        if there[key] != here.get(key)
    ]
    assert not differing, f"(student, task, field, there, here): {differing}"
    failed = {(r["student"], r["task"]): r["run"] for r in rows("there") if r["status"] == "fail"}
    assert failed == {
        ("noglass", "glass"): "ok",
        ("loop", "glass"): "timeout",
        ("link", "glass"): "no-output",
        ("fourkids", "glass"): "memory",
        ("quota", "glass"): "timeout",
        ("garbage", "spot"): "ok",
        ("garbage", "glass"): "ok",
    }
    for student in ("honest", "noglass"):
        assert (tmp_path / "there" / "gradescope" / student / "results.json").read_text() == (
            tmp_path / "here" / "gradescope" / student / "results.json"
        ).read_text()
    assert left_running() == []


def test_a_second_run_resumes_and_runs_again_only_a_changed_program(tmp_path, listener):
    """A kept grade is taken as it was (its run's time included), a failed run's too, while the program's
    files are the same; a student whose files changed is run again."""
    check_sandbox()
    scenes, subs = make_class(tmp_path, listener[0], ["honest", "link", "noglass"])
    first = grade(tmp_path, scenes, subs)[1]
    assert first["link", "glass"]["run"] == "no-output"
    (subs / "noglass" / "mistakes.txt").write_text("no-shadows\n")
    second = grade(tmp_path, scenes, subs)[1]
    for student in ("honest", "link"):
        for task in ("spot", "glass"):
            assert second[student, task] == first[student, task]
    assert second["noglass", "spot"]["status"] == "fail" and "no-shadows" in second["noglass", "spot"]["mistakes"]
