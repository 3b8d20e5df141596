"""A class of students' programs graded in one command (grade-class --run): honest ones pass, buggy ones fail
with their mistakes named (by experiment where the image alone cannot), hostile ones are contained, each pair
with its reason, nothing leaked or left running; a hidden task shows a student only what tasks.json says.

Every program is tests/programs/tracer.py (the system's python3, the standard library only), a buggy one with a
mistake switched on, a hostile one with a few lines before it that misbehave on the task ``glass`` only."""

import json
import socket
import tempfile
import threading
from pathlib import Path

import pytest
from test_cluster import dask as cluster_fixture  # noqa: F401  (the fixture 'dask': a scheduler, two workers)

from service.cli import main
from service.programs import check_sandbox

from helpers import left_in_sandboxes

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
}
BUGGY = {"noshadow": "no-shadows", "hardspot": "spot-hard-edge", "noglass": "no-refraction"}


def left_running() -> list[str]:
    """What this test's runs left running: a sandbox or anything under it, or the hostile daemon's sleep;
    zombies do not count."""
    return left_in_sandboxes("876.543")


def scratch() -> set[str]:
    """The temporary folders of runs, builds and scenes of this test session (tests/conftest.py gives it a
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
        (folder / "tracer.py").write_text(prefix + tracer)
        (folder / "mistakes.txt").write_text(BUGGY.get(student, "") + f"\n# {SECRET}\n")
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
    assert "24 pairs: 15 passed, 9 failed, 0 missing, 0 invalid" in summary

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


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--run", "python3 tracer.py {scene}"], "names no {output}"),
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


def test_the_same_class_on_a_dask_cluster_gives_the_same_report(tmp_path, listener, request):
    """Each student's program a task of a worker's (two workers on 127.0.0.1), each run in its own sandbox."""
    check_sandbox()
    address = request.getfixturevalue("cluster_fixture")[0]
    scenes, subs = make_class(tmp_path, listener[0], ["honest", "noglass", "loop", "link"])
    here = tmp_path / "here"
    there = tmp_path / "there"
    for report, more in ((here, []), (there, ["--cluster", address])):
        assert (
            main(
                [
                    "grade-class",
                    str(scenes),
                    str(subs),
                    "-o",
                    str(report),
                    "--tasks",
                    str(tmp_path / "tasks.json"),
                    "--run",
                    RUN,
                    *LIMITS,
                    "-q",
                    *more,
                ]
            )
            == 0
        )

    def rows(report: Path) -> list[dict]:
        return [
            {k: v for k, v in r.items() if k != "run_seconds"} for r in json.loads((report / "report.json").read_text())
        ]

    assert rows(there) == rows(here)
    assert {(r["student"], r["task"]): r["status"] for r in rows(there) if r["status"] == "fail"} == {
        ("noglass", "glass"): "fail",
        ("loop", "glass"): "fail",
        ("link", "glass"): "fail",
    }
    for student in ("honest", "noglass"):
        assert (there / "gradescope" / student / "results.json").read_text() == (
            here / "gradescope" / student / "results.json"
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
