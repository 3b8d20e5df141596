"""What a student reads of a grade (service.classgrade.feedback): a program's failed run without its exit
status, and a hidden task's score kept out of the total a student sees until the grades are published."""

from service.classgrade.feedback import WITHHELD, gradescope
from service.classgrade.feedback import test_output as told
from service.classgrade.taskfile import TaskSettings


def failed_run(reason: str, run: str) -> dict:
    """A report's row of a program's run that failed, as the TA's report keeps it."""
    return {
        "task": "cornell",
        "status": "fail",
        "reason": reason,
        "run": run,
        "likely": "",
        "experiment": None,
        "score": 0.0,
        "points": 3.0,
    }


def test_a_run_that_failed_is_told_as_crashed_or_timed_out_without_its_exit_status():
    crashed = failed_run("the run failed: crashed: crashed (exit 43)", "crashed")
    memory = failed_run("the run failed: memory: ran out of memory (limit 2 GiB; exit 1)", "memory")
    slow = failed_run("the run failed: timeout: still running at the wall-time limit of 60 s; killed", "timeout")
    build = failed_run("the build failed: crashed: crashed (exit 2)", "crashed")
    for show in ("images", "diagnosis", "verdict"):
        assert told(crashed, show) == "fail: the run failed: crashed"
        assert told(memory, show) == "fail: the run failed: crashed"
        assert told(slow, show) == "fail: the run failed: timed out"
        assert told(build, show) == "fail: the build failed: crashed"
    assert told(crashed, "verdict-only") == "failed"


def test_a_hidden_task_worth_points_keeps_the_total_from_the_student_until_published():
    rows = [
        {
            "task": "cornell",
            "status": "pass",
            "reason": "",
            "fraction_off_nearby": 0.0,
            "max_fraction": 0.001,
            "score": 3.0,
            "points": 3.0,
        },
        {**failed_run("the run failed: crashed: crashed (exit 43)", "crashed"), "task": "secret"},
    ]
    shown = {"cornell": TaskSettings(points=3), "secret": TaskSettings(points=3, visibility="hidden")}
    results = gradescope(rows, shown)
    assert results["score"] == 3.0
    assert [t["name"] for t in results["tests"]] == ["cornell", "secret", WITHHELD["name"]]
    assert results["tests"][-1]["visibility"] == "after_published" and results["tests"][-1]["max_score"] == 0
    visible = {"cornell": TaskSettings(points=3), "secret": TaskSettings(points=3)}
    assert [t["name"] for t in gradescope(rows, visible)["tests"]] == ["cornell", "secret"]
    nothing = {"cornell": TaskSettings(points=3), "secret": TaskSettings(points=0, visibility="hidden")}
    rows[1] = {**rows[1], "points": 0.0}  # (a hidden test worth nothing: as Gradescope means one)
    assert [t["name"] for t in gradescope(rows, nothing)["tests"]] == ["cornell", "secret"]
