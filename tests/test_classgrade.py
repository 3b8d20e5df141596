"""Grading a whole class: every status and reason, per-student scenes, reuse, atomic reports, the service."""

import csv
import json
import shutil
import urllib.request
from pathlib import Path

import numpy as np
import pytest

import schemas
import tracer
from service import classgrade
from service.classgrade import ClassRun, submissions
from service.classgrade import report as report_module
from service.classgrade.feedback import WITHHELD
from service.cli import main

from helpers import scene_dict
from server import running_server


def small(name: str, **image) -> dict:
    data = scene_dict(name)
    data["image"].update({"width": 40, "height": 30, **image})
    return data


def png(pixels) -> bytes:
    return tracer.encode_png(pixels)


def rendered(data: dict) -> np.ndarray:
    return tracer.render(schemas.validate_scene(json.loads(json.dumps(data))))


@pytest.fixture(scope="module")
def klass(tmp_path_factory):
    """Two tasks; students: good, bad (a light missing), copycat (someone else's own scene), own (their own
    scene, from the TA's student-scenes folder, right), none (nothing), junk (not a PNG, wrong size), cheat (a
    scene of their own among the submissions, and a black image)."""
    root = tmp_path_factory.mktemp("class")
    scenes, subs, own_scenes = root / "scenes", root / "subs", root / "own"
    scenes.mkdir()
    tasks = {"balls": small("01_three_spheres"), "lamps": small("02_all_lights")}
    for task, data in tasks.items():
        (scenes / f"{task}.json").write_text(json.dumps(data))
    (scenes / "README.txt").write_text("not a task")
    right = {task: rendered(data) for task, data in tasks.items()}

    def put(student, name, data, folder=subs):
        (folder / student).mkdir(parents=True, exist_ok=True)
        (folder / student / name).write_bytes(data if isinstance(data, bytes) else data.encode())

    for task in tasks:
        put("good", f"{task}.png", png(right[task]))
    dim = json.loads(json.dumps(tasks["lamps"]))
    dim["lights"] = dim["lights"][:-1]
    put("bad", "balls.png", png(right["balls"]))
    put("bad", "lamps.png", png(rendered(dim)))
    own = json.loads(json.dumps(tasks["balls"]))
    for obj in own["objects"]:
        if obj["type"] == "sphere":
            obj["center"][0] += 0.4
    own_png = png(rendered(own))
    put("own", "balls.json", json.dumps(own), folder=own_scenes)
    put("own", "balls.png", own_png)
    put("own", "lamps.png", png(right["lamps"]))
    put("copycat", "balls.png", own_png)
    put("copycat", "lamps.png", png(right["lamps"]))
    (subs / "none").mkdir()
    put("junk", "balls.png", b"GIF89a not a png")
    put("junk", "lamps.png", png(right["lamps"][:10, :10]))
    put("junk", "essay.docx", b"?")
    empty = {"camera": tasks["balls"]["camera"], "image": tasks["balls"]["image"]}  # nothing to see: all black
    put("cheat", "balls.json", json.dumps(empty))
    put("cheat", "balls.png", png(np.zeros_like(right["balls"])))
    return scenes, subs, own_scenes


def by_pair(rows):
    return {(r["student"], r["task"]): r for r in rows}


def cli_reason(capsys, scene, image):
    """What the single ``phongray grade`` says of this pair (after ``phongray: ``)."""
    code = main(["grade", str(scene), str(image)])
    err = capsys.readouterr().err.strip()
    assert code == 2
    return err.removeprefix("phongray: ")


def grade(klass, report, **kw):
    scenes, subs, own = klass
    return classgrade.grade_class(ClassRun(scenes, subs, report, jobs=2, student_scenes=own, **kw))


@pytest.fixture(scope="module")
def graded(klass, tmp_path_factory):
    """The class graded once, into a report folder that the tests given it only read: (outcome, folder)."""
    report = tmp_path_factory.mktemp("graded") / "report"
    return grade(klass, report), report


def test_every_status_and_reason(klass, graded, capsys):
    scenes, subs, _ = klass
    outcome, _ = graded
    rows = by_pair(outcome.rows)
    assert len(outcome.rows) == 7 * 2  # every (student, task) pair, exactly once
    assert {k: r["status"] for k, r in rows.items()} == {
        ("bad", "balls"): "pass",
        ("bad", "lamps"): "fail",
        ("cheat", "balls"): "fail",
        ("cheat", "lamps"): "missing",
        ("copycat", "balls"): "fail",
        ("copycat", "lamps"): "pass",
        ("good", "balls"): "pass",
        ("good", "lamps"): "pass",
        ("junk", "balls"): "invalid",
        ("junk", "lamps"): "invalid",
        ("none", "balls"): "missing",
        ("none", "lamps"): "missing",
        ("own", "balls"): "pass",
        ("own", "lamps"): "pass",
    }
    assert rows[("own", "balls")]["scene"] == "own" and rows[("copycat", "balls")]["scene"] == "shared"
    assert rows[("junk", "balls")]["reason"] == cli_reason(capsys, scenes / "balls.json", subs / "junk/balls.png")
    assert rows[("junk", "lamps")]["reason"] == cli_reason(capsys, scenes / "lamps.json", subs / "junk/lamps.png")
    assert rows[("junk", "balls")]["reason"].endswith("image is a GIF; PNG or PPM required")
    assert rows[("none", "lamps")]["reason"] == "no lamps.png"
    assert sorted(outcome.ignored) == [
        (f"{scenes}/README.txt", "not a task scene (<task>.json)"),
        (f"{subs}/cheat/balls.json", submissions.SCENE_IGNORED),
        (f"{subs}/junk/essay.docx", "matches no task"),
    ]
    assert rows[("bad", "lamps")]["fraction_off_nearby"] > 0.01 and rows[("good", "lamps")]["max_error"] == 0
    assert outcome.renders == 3  # two shared scenes and one student's own


def test_a_scene_among_the_submissions_cannot_change_the_task(graded):
    """A student's balls.json (an empty scene) and a black image: graded against the task's scene, it fails."""
    rows = by_pair(graded[0].rows)
    cheat = rows[("cheat", "balls")]
    assert cheat["status"] == "fail" and cheat["scene"] == "shared" and cheat["fraction_off_nearby"] > 0.1
    assert "of the pixels are off even nearby" in cheat["reason"]


def test_a_student_cannot_change_their_task_from_the_command_line(klass, tmp_path, capsys):
    scenes, subs, _ = klass
    assert main(["grade-class", str(scenes), str(subs), "-o", str(tmp_path / "r")]) == 0
    rows = by_pair(json.loads((tmp_path / "r" / "report.json").read_text()))
    assert rows[("cheat", "balls")]["status"] == "fail" and rows[("cheat", "balls")]["scene"] == "shared"
    assert f"ignored: {subs}/cheat/balls.json: {submissions.SCENE_IGNORED}" in capsys.readouterr().err


def test_fail_rows_give_their_reason(graded):
    rows = by_pair(graded[0].rows)
    bad = rows[("bad", "lamps")]
    assert bad["reason"].startswith(f"{100 * bad['fraction_off_nearby']:.2f} % of the pixels are off even nearby")
    assert bad["reason"].endswith("at most 0.10 % may be")
    assert rows[("good", "lamps")]["reason"] == ""


def test_the_report_files_agree_and_link_what_exists(graded):
    outcome, report = graded
    rows = json.loads((report / "report.json").read_text())
    assert rows == json.loads(json.dumps(outcome.rows))
    with open(report / "report.csv") as f:
        table = list(csv.DictReader(f))
    assert [(r["student"], r["task"], r["status"]) for r in table] == [
        (r["student"], r["task"], r["status"]) for r in rows
    ]
    assert list(table[0]) == report_module.COLUMNS
    for r in rows:
        for key in ("reference", "submission", "heatmap"):
            if r[key]:
                assert (report / r[key]).is_file()
        assert (r["heatmap"] is not None) == (r["status"] in ("pass", "fail"))
    page = (report / "index.html").read_text()
    assert page.count('<td class="total">') == 7  # a total per student
    assert page.count('<td class="') - 7 == len(rows) and page.count("3/7") == 2
    assert page.count('class="legend"') == sum(r["heatmap"] is not None for r in rows)  # beside each heat-map
    assert page.rstrip().endswith("</html>")
    assert "http" not in page.replace("http-equiv", "")  # nothing from the network


def test_a_rerun_reuses_its_references_and_gives_the_same_report(klass, tmp_path):
    report = tmp_path / "report"
    first = grade(klass, report)
    before = (report / "report.json").read_bytes()
    again = grade(klass, report)
    assert first.renders == 3 and again.renders == 0
    assert (report / "report.json").read_bytes() == before


def test_a_rerun_after_a_scene_changed_leaves_no_stale_reference(klass, tmp_path):
    """The changed task's old reference is gone; the other task's (unchanged) is kept, not rendered again."""
    scenes, subs, own = klass
    changed = tmp_path / "scenes"
    shutil.copytree(scenes, changed)
    report = tmp_path / "report"
    grade((changed, subs, own), report)
    before = {p.name for p in (report / "references").glob("*.png")}
    data = json.loads((changed / "lamps.json").read_text())
    data["image"]["background"] = [0.2, 0.1, 0.0]
    (changed / "lamps.json").write_text(json.dumps(data))
    again = grade((changed, subs, own), report)
    after = {p.name for p in (report / "references").glob("*.png")}
    assert again.renders == 1 and len(after) == len(before) == 3 and len(after - before) == 1
    listed = {Path(r["reference"]).name for r in json.loads((report / "report.json").read_text()) if r["reference"]}
    assert listed == after


def test_the_cli_without_diagnosis_and_quiet(klass, tmp_path, capsys):
    """--no-diagnosis: the failing pairs name no likely mistake; -q: no summary line (errors and ignored files
    are still told)."""
    scenes, subs, own = klass
    report = tmp_path / "r"
    args = ["grade-class", str(scenes), str(subs), "-o", str(report), "--jobs", "2", "--student-scenes", str(own)]
    assert main(args) == 0
    assert "14 pairs: " in capsys.readouterr().out
    diagnosed = {r["student"] + "/" + r["task"]: r["likely"] for r in json.loads((report / "report.json").read_text())}
    assert diagnosed["bad/lamps"]
    plain = tmp_path / "plain"
    assert main([*args[:4], str(plain), *args[5:], "--no-diagnosis", "-q"]) == 0
    out, err = capsys.readouterr()
    assert out == "" and "ignored: " in err
    rows = json.loads((plain / "report.json").read_text())
    assert sum(r["status"] == "fail" for r in rows) == 3 and not any(r["likely"] for r in rows)
    assert main([*args[:4], str(plain), *args[5:], "-q"]) == 0  # again, diagnosing: not the kept grades taken
    capsys.readouterr()
    again = {r["student"] + "/" + r["task"]: r["likely"] for r in json.loads((plain / "report.json").read_text())}
    assert again == diagnosed


def test_an_interrupted_rerun_leaves_every_report_file_whole(klass, tmp_path, monkeypatch):
    report = tmp_path / "report"
    grade(klass, report)
    real = report_module.os.replace
    calls = []

    def replace(src, dst):
        calls.append(dst)
        if str(dst).endswith("report.csv"):
            raise KeyboardInterrupt  # Ctrl-C in the middle of writing the report
        real(src, dst)

    monkeypatch.setattr(report_module.os, "replace", replace)
    with pytest.raises(KeyboardInterrupt):
        grade(klass, report)
    monkeypatch.undo()
    assert len(json.loads((report / "report.json").read_text())) == 14
    with open(report / "report.csv") as f:
        assert len(list(csv.DictReader(f))) == 14
    assert (report / "index.html").read_text().rstrip().endswith("</html>")


def test_the_cli_prints_a_summary_and_exits_0_even_with_failures(klass, tmp_path, capsys):
    scenes, subs, own = klass
    assert (
        main(
            [
                "grade-class",
                str(scenes),
                str(subs),
                "-o",
                str(tmp_path / "r"),
                "--jobs",
                "2",
                "--student-scenes",
                str(own),
            ]
        )
        == 0
    )
    out, err = capsys.readouterr()
    assert "14 pairs: 6 passed, 3 failed, 3 missing, 2 invalid" in out
    assert f"ignored: {subs}/cheat/balls.json: {submissions.SCENE_IGNORED}" in err.splitlines()


def test_the_same_report_through_a_running_service(klass, tmp_path):
    """report.json byte for byte: the same rows, numbers, reasons, references and heat-maps."""
    grade(klass, tmp_path / "local")
    with running_server(tmp_path, max_concurrent_renders="1") as (url, _):
        grade(klass, tmp_path / "remote", server=url)
    assert (tmp_path / "remote" / "report.json").read_bytes() == (tmp_path / "local" / "report.json").read_bytes()
    for name in ("heatmaps/bad/lamps.png", "heatmaps/copycat/balls.png", "gradescope/bad/results.json"):
        assert (tmp_path / "remote" / name).read_bytes() == (tmp_path / "local" / name).read_bytes(), name


# -- the teaching assistant's faults stop the run: exit 2, one line, nobody graded ----------------------------


def ta_fault(capsys, *args):
    """Run grade-class; it must stop with exit 2 and one line (returned), leaving no report."""
    code = main(["grade-class", *map(str, args)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    return err.removeprefix("phongray: ").strip()


def test_an_invalid_task_scene_stops_the_run_before_any_grading(klass, tmp_path, capsys):
    scenes, subs, own = klass
    broken = tmp_path / "scenes"
    shutil.copytree(scenes, broken)
    data = json.loads((broken / "lamps.json").read_text())
    next(o for o in data["objects"] if o["type"] == "sphere")["radius"] = -1
    (broken / "lamps.json").write_text(json.dumps(data, indent=1))
    line = next(i for i, t in enumerate((broken / "lamps.json").read_text().splitlines(), 1) if '"radius": -1' in t)
    said = ta_fault(capsys, broken, subs, "-o", tmp_path / "r")
    assert said.startswith(f"{broken}/lamps.json:{line}: objects[") and ".radius: must be > 0" in said
    assert not (tmp_path / "r" / "report.json").exists() and not (tmp_path / "r" / "references").exists()


def test_an_invalid_student_scene_of_the_tas_stops_the_run(klass, tmp_path, capsys):
    scenes, subs, own = klass
    mine = tmp_path / "own"
    shutil.copytree(own, mine)
    (mine / "own" / "balls.json").write_text('{"camera": {}}')
    said = ta_fault(capsys, scenes, subs, "-o", tmp_path / "r", "--student-scenes", mine)
    assert said.startswith(f"{mine}/own/balls.json:1: camera.position: required")
    (mine / "own" / "balls.json").unlink()
    (mine / "own" / "ballz.json").write_text("{}")
    assert ta_fault(capsys, scenes, subs, "-o", tmp_path / "r", "--student-scenes", mine) == (
        f"{mine}/own/ballz.json: names no task (the tasks are balls, lamps)"
    )


def test_an_unusable_report_folder_stops_the_run(klass, tmp_path, capsys):
    scenes, subs, own = klass
    (tmp_path / "file").write_text("")
    said = ta_fault(capsys, scenes, subs, "-o", tmp_path / "file" / "report")
    assert said.startswith(f"{tmp_path}/file/report: cannot write the report there: ")


def test_unusable_input_exits_2_with_one_line(tmp_path, capsys):
    (tmp_path / "scenes").mkdir()
    (tmp_path / "subs").mkdir()
    assert ta_fault(capsys, tmp_path / "scenes", tmp_path / "subs", "-o", tmp_path / "r") == (
        f"{tmp_path}/scenes: no task scenes (<task>.json)"
    )
    assert "cannot read" in ta_fault(capsys, tmp_path / "nowhere", tmp_path / "subs", "-o", tmp_path / "r")


def test_a_wrong_or_missing_api_key_or_a_dead_server_stops_the_run(klass, tmp_path, capsys, monkeypatch):
    scenes, subs, own = klass
    monkeypatch.delenv("PHONGRAY_API_KEY", raising=False)
    args = [scenes, subs, "-o", tmp_path / "r"]
    with running_server(tmp_path, api_key="sesame") as (url, _):
        for key in (["--api-key", "wrong"], []):
            said = ta_fault(capsys, *args, "--server", url, *key)
            assert said.startswith(f"--server {url}: server answered 401: missing or wrong API key"), said
        health = json.loads(urllib.request.urlopen(url + "/healthz").read())
        assert health["renders"] == 0  # nothing was rendered, let alone graded
    said = ta_fault(capsys, *args, "--server", url)  # the server is gone now
    assert said.startswith(f"--server {url}: cannot reach {url}/healthz: ")
    assert not (tmp_path / "r").exists()  # not even an empty report folder is left behind


def test_a_tasks_file_gives_points_and_thresholds_per_task(klass, tmp_path):
    tasks = tmp_path / "tasks.json"
    tasks.write_text(json.dumps({"lamps": {"points": 4, "tolerance": 255}, "balls": {"visibility": "hidden"}}))
    report = tmp_path / "r"
    rows = by_pair(grade(klass, report, tasks_file=tasks).rows)
    assert rows[("bad", "lamps")]["status"] == "pass" and rows[("bad", "lamps")]["tolerance"] == 255
    assert rows[("bad", "balls")]["tolerance"] == 2 and rows[("bad", "lamps")]["score"] == 4
    results = json.loads((report / "gradescope" / "bad" / "results.json").read_text())
    assert results == {
        "score": 5.0,
        "visibility": "visible",
        "tests": [
            {
                "name": "balls",
                "score": 1.0,
                "max_score": 1.0,
                "status": "passed",
                "visibility": "hidden",
                "output": "passed: 0.00 % of the pixels off even nearby (at most 0.10 % may be)",
            },
            {
                "name": "lamps",
                "score": 4.0,
                "max_score": 4.0,
                "status": "passed",
                "visibility": "visible",
                "output": "passed: 0.00 % of the pixels off even nearby (at most 0.10 % may be)",
            },
            WITHHELD,  # (the hidden task's point is in the total: the total waits for the grades' publication)
        ],
    }


def test_gradescope_results_of_every_student(graded):
    outcome, report = graded
    rows = outcome.rows
    for student in {r["student"] for r in rows}:
        results = json.loads((report / "gradescope" / student / "results.json").read_text())
        mine = [r for r in rows if r["student"] == student]
        assert results["score"] == sum(r["status"] == "pass" for r in mine)
        for test, row in zip(results["tests"], mine, strict=True):
            assert set(test) == {"name", "score", "max_score", "status", "output", "visibility"}
            assert test["status"] == ("passed" if row["status"] == "pass" else "failed")
            likely = f"\nLikely: {row['likely']}" if row["likely"] else ""
            assert row["status"] == "pass" or test["output"] == f"{row['status']}: {row['reason']}{likely}"


def test_each_failing_pair_gets_its_likely_mistake_and_each_task_a_summary(tmp_path):
    from tracer.scene.variants import VARIANTS

    scenes, subs = tmp_path / "scenes", tmp_path / "subs"
    scenes.mkdir()
    data = small("02_all_lights")
    (scenes / "lamps.json").write_text(json.dumps(data))
    scene = schemas.validate_scene(data)
    for student, mistake in (
        ("ada", None),
        ("bob", "no-attenuation"),
        ("cy", "no-attenuation"),
        ("dee", "image-flipped"),
    ):
        (subs / student).mkdir(parents=True)
        options = VARIANTS[mistake][0] if mistake else None
        pixels = tracer.Renderer(scene, options).pixels() if options else tracer.render(scene)
        (subs / student / "lamps.png").write_bytes(png(pixels))
    report = tmp_path / "r"
    rows = by_pair(grade((scenes, subs, None), report).rows)
    assert rows[("ada", "lamps")]["status"] == "pass" and rows[("ada", "lamps")]["likely"] == ""
    for student in ("bob", "cy"):
        assert rows[(student, "lamps")]["likely"] == "no attenuation of point, spot and area lights"
    assert rows[("dee", "lamps")]["likely"] == "the image flipped vertically"
    page = (report / "index.html").read_text()
    assert "<li>2 of 3: no attenuation of point, spot and area lights</li>" in page
    assert "<li>1 of 3: the image flipped vertically</li>" in page
    with open(report / "report.csv", newline="") as f:
        assert {r["student"]: r["likely"] for r in csv.DictReader(f)}["bob"].startswith("no attenuation")
    results = json.loads((report / "gradescope" / "dee" / "results.json").read_text())
    assert results["tests"][0]["output"].endswith("\nLikely: the image flipped vertically")


@pytest.mark.parametrize(
    "content, says",
    [
        ('{"lamps": {"points": -1}}', ":1: lamps.points: must be ≥ 0"),
        ('{"lamps": {"points": 1e308}}', ":1: lamps.points: must be ≤ 1e+06"),  # (two of them: an infinite total)
        ('{"lampz": {}}', ": no task lampz (did you mean 'lamps'?) (the tasks are balls, lamps)"),
        ('{"lamps": {"tolerence": 3}}', ":1: lamps.tolerence: unknown key (did you mean 'tolerance'?)"),
        ('{"lamps": {"point": 3}}', ":1: lamps.point: unknown key (did you mean 'points'?)"),
        (
            '{"lamps": {"points": 2,\n "deductions": {"no-shadow": 1}}}',
            ":2: lamps.deductions.no-shadow: no such mistake (did you mean 'no-shadows'?) "
            "(the ids are in docs/grading.md)",
        ),
        ('{"lamps": {"deductions": {"gamma": -1}}}', ":1: lamps.deductions.gamma: must be ≥ 0"),
        # a number as a string, a boolean, a number too large to be finite: the TA's mistake, not 5, 1 or infinity
        ('{"lamps": {"points": "5"}}', ":1: lamps.points: must be a number"),
        ('{"lamps": {"points": true}}', ":1: lamps.points: must be a number"),
        ('{"lamps": {"tolerance": "3"}}', ":1: lamps.tolerance: must be a number"),
        ('{"lamps": {"points": 1e400}}', ":1: lamps.points: must be a finite number"),
        ('{"lamps": {"points": 2, "deductions": {"gamma": "1"}}}', ":1: lamps.deductions.gamma: must be a number"),
        # a deduction larger than the task's points (given, or the default 1)
        (
            '{"lamps": {"points": 2,\n "deductions": {"gamma": 5}}}',
            ":2: lamps.deductions.gamma: must be ≤ the task's points, 2",
        ),
        (
            '{"lamps": {"deductions": {"gamma": 4}}}',
            ":1: lamps.deductions.gamma: must be ≤ the task's points, 1 (points not given: the default)",
        ),
        # every task's deduction ("*") too large for one task: said at the "*", naming the task
        (
            '{"*": {"deductions": {"gamma": 3}},\n "balls": {"points": 5}}',
            ":1: *.deductions.gamma: must be ≤ the points of task lamps, 1 (points not given: the default)",
        ),
        # null is no number of points (a threshold's null is the command's: points has no such default)
        ('{"lamps": {"points": null}}', ":1: lamps.points: must be a number (leave the key out for the default, 1"),
    ],
)
def test_a_bad_tasks_file_stops_the_run(klass, tmp_path, capsys, content, says):
    scenes, subs, _ = klass
    (tmp_path / "t.json").write_text(content)
    said = ta_fault(capsys, scenes, subs, "-o", tmp_path / "r", "--tasks", tmp_path / "t.json")
    assert said.startswith(f"{tmp_path}/t.json{says}"), said


# -- partial credit, totals and the gradebook ------------------------------------------------------------------

#: the mistaken class: each student's mistake in the one task, lamps (None: right; "black": no known mistake)
MISTAKEN = {
    "ada": None,
    "bob": "no-attenuation",
    "cy": "no-attenuation",
    "dee": "image-flipped",
    "fay": "gamma",
    "gil": "no-specular",
    "hal": "black",
}


@pytest.fixture(scope="module")
def mistaken(tmp_path_factory):
    """One task (lamps, 4 points) and a student per classic mistake, graded with deductions: (report, rows)."""
    from tracer.scene.variants import VARIANTS

    root = tmp_path_factory.mktemp("mistaken")
    scenes, subs = root / "scenes", root / "subs"
    scenes.mkdir()
    data = small("02_all_lights")
    (scenes / "lamps.json").write_text(json.dumps(data))
    scene = schemas.validate_scene(data)
    for student, mistake in MISTAKEN.items():
        (subs / student).mkdir(parents=True)
        pixels = (
            tracer.render(scene)
            if mistake is None
            else np.zeros_like(tracer.render(scene))
            if mistake == "black"
            else tracer.Renderer(scene, VARIANTS[mistake][0]).pixels()
        )
        (subs / student / "lamps.png").write_bytes(png(pixels))
    (subs / "ivy").mkdir()  # nothing sent
    tasks = root / "tasks.json"
    tasks.write_text(json.dumps({"lamps": {"points": 4, "deductions": DEDUCTIONS}}))
    report = root / "report"
    outcome = classgrade.grade_class(ClassRun(scenes, subs, report, jobs=2, tasks_file=tasks))
    return report, {r["student"]: r for r in outcome.rows}


DEDUCTIONS = {"no-attenuation": 1.5, "image-flipped": 4, "no-specular": 0.25}
#: the mistakes whose image the lamps task cannot tell from another's: the diagnosis gives every reading (a
#: reflected vector of the wrong sign lights no highlight there either), and the deduction is for what it shows
READINGS = {"no-specular": ["no-specular", "reflect-sign"]}


def test_an_image_whose_one_fault_has_a_deduction_scores_the_points_less_it(mistaken):
    _, rows = mistaken
    for student, mistake in MISTAKEN.items():
        row = rows[student]
        assert row["mistakes"] == (READINGS.get(mistake, [mistake]) if mistake not in (None, "black") else []), row
        expected = 4.0 if mistake is None else max(0.0, 4 - DEDUCTIONS[mistake]) if mistake in DEDUCTIONS else 0.0
        assert row["score"] == expected and row["points"] == 4.0, (student, row["score"])
        assert row["deducted"] == (mistake if mistake in DEDUCTIONS else None)
    assert rows["dee"]["score"] == 0.0 and rows["ivy"]["score"] == 0.0  # all points deducted; nothing sent: 0


def test_the_gradebook_the_totals_and_gradescope_agree(mistaken):
    report, rows = mistaken
    with open(report / "gradebook.csv", newline="") as f:
        table = list(csv.reader(f))
    assert table[0] == ["student", "id", "lamps", "total", "late"]
    assert [r[0] for r in table[1:]] == sorted(rows)
    page = (report / "index.html").read_text()
    for student, lms_id, lamps, total, late in table[1:]:
        assert lms_id == late == ""  # (folders of no learning-management system, which marks nothing late)
        assert float(lamps) == float(total) == rows[student]["score"]
        results = json.loads((report / "gradescope" / student / "results.json").read_text())
        assert results["score"] == float(total) == sum(t["score"] for t in results["tests"])
        assert f'<td class="total">{float(total):g} / 4</td>' in page
    deducted = sum(r["deducted"] is not None for r in rows.values())
    assert page.count('<td class="fail partial">') == deducted == sum(m in DEDUCTIONS for m in MISTAKEN.values())
    assert json.loads((report / "gradescope" / "bob" / "results.json").read_text())["tests"][0]["output"].endswith(
        "\nLikely: no attenuation of point, spot and area lights\nPartial credit: 2.5 of 4 points (no attenuation "
        "of point, spot and area lights: -1.5)"
    )


def test_the_report_lists_every_likely_mistake_of_a_task(mistaken):
    report, rows = mistaken
    page = (report / "index.html").read_text()
    named = {r["likely"] for r in rows.values() if r["status"] == "fail"}
    assert len(named) > 3
    footer = page[page.index("likely mistakes<small>") : page.index("</tfoot>")]
    assert footer.count("<li>") == 3 + 1 and f"… and {len(named) - 3} more</a>" in footer
    assert '<a href="#likely-lamps">' in footer
    every = page[page.index('<h3 id="likely-lamps">') :]
    every = every[: every.index("</ul>")]
    for mistake in named:
        assert f": {mistake}</li>" in every, mistake


def test_the_mistake_ids_are_documented_and_in_grade_json(mistaken, tmp_path, capsys):
    import re
    from pathlib import Path

    from tracer.scene.variants import VARIANTS

    docs = (Path(__file__).parent.parent / "docs" / "grading.md").read_text()
    section = docs[docs.index("\n### The mistake ids\n") :]
    section = section[: section.index("\n## ")]
    table = dict(re.findall(r"^\| `([a-z-]+)` \| (.+) \|$", section, re.M))
    assert table == {name: words for name, (_, words) in VARIANTS.items()}
    report, _ = mistaken
    scene = report.parent / "scenes" / "lamps.json"
    assert main(["grade", "--json", str(scene), str(report.parent / "subs" / "bob" / "lamps.png")]) == 1
    diagnosis = json.loads(capsys.readouterr().out)["diagnosis"]
    assert diagnosis["causes"][0]["variant"] == "no-attenuation" and diagnosis["causes"][0]["passes"]


def test_the_summary_counts_one_pair_and_one_reference_in_the_singular():
    from service.classgrade.report import summary

    one = summary([{"status": "pass"}], 1, 0.5)
    assert one.startswith("1 pair: 1 passed") and "; 1 reference rendered;" in one
    two = summary([{"status": "pass"}, {"status": "fail"}], 2, 0.5)
    assert two.startswith("2 pairs: 1 passed, 1 failed") and "; 2 references rendered;" in two


def test_a_grade_record_has_the_reports_columns_in_their_order():
    from dataclasses import fields

    from service.classgrade.records import Row

    assert [f.name for f in fields(Row)] == report_module.COLUMNS


def test_a_programs_failed_run_is_named_in_the_report_not_left_undiagnosed():
    from service.classgrade.report import likely_by_task

    rows = [
        {"task": "spot", "status": "fail", "likely": None, "run": "timeout"},
        {"task": "spot", "status": "fail", "likely": None, "run": "ok"},
        {"task": "spot", "status": "fail", "likely": "no shadow rays", "run": "ok"},
    ]
    assert likely_by_task(rows, ["spot"])["spot"] == [
        ("no shadow rays", 1, 3),
        ("not diagnosed", 1, 3),
        ("run: timeout", 1, 3),
    ]


def test_a_task_most_students_fail_for_one_reason_is_the_tas_to_look_at(tmp_path, capsys):
    """A task scene of the wrong size: every student's image is 'invalid' for the same reason.  The run goes on
    (exit 0, each row as it is), and the TA reads one warning naming the task and the reason."""
    folder = Path(__file__).resolve().parent.parent / "examples" / "class"
    shutil.copytree(folder / "scenes", tmp_path / "scenes")
    shutil.copytree(folder / "submissions", tmp_path / "subs")
    data = json.loads((tmp_path / "scenes" / "spheres.json").read_text())
    data["image"].update(width=40, height=30)
    (tmp_path / "scenes" / "spheres.json").write_text(json.dumps(data))
    assert main(["grade-class", str(tmp_path / "scenes"), str(tmp_path / "subs"), "-o", str(tmp_path / "r"), "-q"]) == 0
    warnings = [line for line in capsys.readouterr().err.splitlines() if line.startswith("warning: ")]
    assert len(warnings) == 1 and warnings[0].startswith("warning: spheres: "), warnings
    assert "students invalid for one reason, 'image is 160×120 pixels, the scene is 40×30'" in warnings[0]
    rows = json.loads((tmp_path / "r" / "report.json").read_text())
    assert all(r["status"] in ("invalid", "missing") for r in rows if r["task"] == "spheres")


def test_most_programs_out_of_memory_ask_whether_the_memory_limit_lets_their_language_start():
    """Node under 512M of address space cannot reserve its code range: every student's run 'ran out of memory'.
    The warning asks about --memory, not about the task."""
    from service.classgrade.job import failed_run
    from service.programs import Reason
    from service.programs.outcome import RunOutcome

    ended = RunOutcome(Reason.MEMORY, "ran out of memory (limit 512 MiB; killed by SIGTRAP)")
    reason = failed_run(ended).reason  # (as a run's row says it)
    rows = [{"task": "spheres", "status": "fail", "reason": reason} for _ in range(3)]
    (warning,) = report_module.alike(rows)
    assert warning.endswith(f"{reason!r}: {report_module.RUNTIME_MEMORY}")
    assert "Node" in report_module.RUNTIME_MEMORY and "--memory" in report_module.RUNTIME_MEMORY


def test_an_ordinary_class_gets_no_warning(tmp_path, capsys):
    folder = Path(__file__).resolve().parent.parent / "examples" / "class"
    args = [str(folder / "scenes"), str(folder / "submissions"), "-o", str(tmp_path / "r"), "-q"]
    assert main(["grade-class", *args, "--tasks", str(folder / "tasks.json")]) == 0
    assert "warning:" not in capsys.readouterr().err


def test_a_tasks_file_among_the_scenes_is_said_to_be_one(tmp_path, capsys):
    folder = Path(__file__).resolve().parent.parent / "examples" / "class"
    shutil.copytree(folder / "scenes", tmp_path / "scenes")
    shutil.copy(folder / "tasks.json", tmp_path / "scenes" / "tasks.json")
    args = [str(tmp_path / "scenes"), str(folder / "submissions"), "-o", str(tmp_path / "r")]
    assert main(["grade-class", *args, "--tasks", str(tmp_path / "scenes" / "tasks.json")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(
        f"phongray: {tmp_path}/scenes/tasks.json: tasks.json among the task scenes is read as a task scene; keep it "
        "beside the scenes folder and give it with --tasks; "
    ), err


def test_a_folder_of_the_tas_own_files_is_no_report_folder(tmp_path, capsys):
    """A report replaces what its own folders held (references/, gradescope/): into a folder of the TA's own
    files that is no report, nothing is written and nothing of theirs removed; a new folder, or an earlier
    report, is written as before."""
    folder = Path(__file__).resolve().parent.parent / "examples" / "class"
    home = tmp_path / "home"
    (home / "references").mkdir(parents=True)
    (home / "references" / "notes.png").write_text("mine")
    args = ["grade-class", str(folder / "scenes"), str(folder / "submissions"), "-q"]
    assert main([*args, "-o", str(home)]) == 2
    assert capsys.readouterr().err == (
        f"phongray: {home}: the folder holds files of its own (references) and no phongray report; write the "
        "report to a new folder\n"
    )
    assert (home / "references" / "notes.png").read_text() == "mine"
    assert main([*args, "-o", str(tmp_path / "r")]) == 0
    assert main([*args, "-o", str(tmp_path / "r")]) == 0  # (an earlier report: written again)
