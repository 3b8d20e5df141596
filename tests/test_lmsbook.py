"""A class's grades going back to its LMS (service/classgrade/lmsbook.py): one class, exported from Canvas and
from Moodle, graded into each LMS's own import file; Canvas's late marks kept, and the late policy applied.

Canvas's importer (Grades → Import) and Moodle's (Upload grading worksheet) are not here to run: the checks
below hold the files to what those importers read, as their documentation and their source describe them."""

import csv
import io
import json
import re
from datetime import datetime

import pytest

import schemas
import tracer
from service.classgrade import ClassError, ClassRun, grade_class
from service.classgrade.lmsbook import MOODLE_COLUMNS, moodle_time

from helpers import scene_dict

TASKS = {"*": {"canvas": "Homework 3 (12345)", "late_penalty": 0.25}, "cornell": {"points": 10}, "whitted_aa": {}}


@pytest.fixture(scope="module")
def images():
    """Two tasks and, for each, its right image and a wrong one (a light left out)."""
    out = {}
    for task, name in (("cornell", "01_three_spheres"), ("whitted_aa", "02_all_lights")):
        data = scene_dict(name)
        data["image"].update(width=32, height=24)
        wrong = {**data, "lights": data["lights"][:-1]}
        out[task] = (data, *(tracer.render_png(schemas.validate_scene(d)) for d in (data, wrong)))
    return out


def a_class(root, images, files):
    """The scenes, tasks.json and the submissions folder ``files`` (name → (task, right?))."""
    (root / "scenes").mkdir(parents=True)
    for task, (data, _, _) in images.items():
        (root / "scenes" / f"{task}.json").write_text(json.dumps(data))
    (root / "tasks.json").write_text(json.dumps(TASKS))
    for name, (task, right) in files.items():
        (root / "subs" / name).parent.mkdir(parents=True, exist_ok=True)
        (root / "subs" / name).write_bytes(images[task][1 if right else 2])


#: one class as Canvas downloads it: ada handed both in late, bo only cornell (on time), cy a wrong whitted_aa
CANVAS = {
    "adamsada_LATE_12345_67890_cornell.png": ("cornell", True),
    "adamsada_late_12345_67891_whitted_aa-1.png": ("whitted_aa", True),
    "libo_222_333_Cornell.png": ("cornell", True),
    "yangcy_444_555_cornell.png": ("cornell", True),
    "yangcy_444_556_whitted_aa.png": ("whitted_aa", False),
}
#: the same class as Moodle downloads it (Moodle marks no file late)
MOODLE = {
    "Ada Adams_100001_assignsubmission_file_/cornell.png": ("cornell", True),
    "Ada Adams_100001_assignsubmission_file_/whitted_aa.png": ("whitted_aa", True),
    "Bo Li_100002_assignsubmission_file_/hw3/Cornell.png": ("cornell", True),
    "Cy Yang_100003_assignsubmission_file_/cornell.png": ("cornell", True),
    "Cy Yang_100003_assignsubmission_file_/whitted_aa.png": ("whitted_aa", False),
}


def graded(root):
    outcome = grade_class(
        ClassRun(
            root / "scenes", root / "subs", root / "report", jobs=1, tasks_file=root / "tasks.json", diagnose=False
        )
    )
    return {(r["student"], r["task"]): r for r in outcome.rows}


def read_csv(path):
    return list(csv.reader(io.StringIO(path.read_text(), newline="")))


def test_a_canvas_export_gives_canvas_s_gradebook_import(tmp_path, images):
    a_class(tmp_path, images, CANVAS)
    rows = graded(tmp_path)
    table = read_csv(tmp_path / "report" / "canvas-gradebook.csv")
    # Canvas's importer: a header row whose first cells are Student, ID, (SIS User ID, SIS Login ID,) Section,
    # then each assignment as "<title> (<id>)"; a row whose first cell holds "Points Possible"; the students
    assert table[0] == ["Student", "ID", "SIS User ID", "SIS Login ID", "Section", "Homework 3 (12345)"]
    assert re.fullmatch(r"(.*)\s\((\d+)\)", table[0][5]).groups() == ("Homework 3", "12345")
    assert table[1] == ["    Points Possible", "", "", "", "", "11"]
    # ada: 10 + 1 earned, late: a quarter of each task's points off (2.5 and 0.25); cy: whitted_aa wrong
    assert table[2:] == [
        ["adamsada", "12345", "", "", "", "8.25"],
        ["libo", "222", "", "", "", "10"],
        ["yangcy", "444", "", "", "", "10"],
    ]
    assert (
        (tmp_path / "report" / "canvas-gradebook.csv")
        .read_text()
        .startswith("Student,ID,SIS User ID,SIS Login ID,Section,Homework 3 (12345)\n    Points Possible,,,,,11\n")
    )
    assert not (tmp_path / "report" / "moodle-grading-worksheet.csv").exists()
    assert {k: (r["late"], r["late_deducted"], r["score"]) for k, r in rows.items() if k[0] == "adamsada"} == {
        ("adamsada", "cornell"): (True, 2.5, 7.5),
        ("adamsada", "whitted_aa"): (True, 0.25, 0.75),
    }
    assert rows[("libo", "cornell")]["late"] is False and rows[("libo", "cornell")]["late_deducted"] is None
    assert {r["lms"] for r in rows.values()} == {"canvas"}


def test_the_same_class_from_moodle_gives_moodle_s_grading_worksheet(tmp_path, images):
    a_class(tmp_path, images, MOODLE)
    before = datetime.now().replace(second=0, microsecond=0)
    graded(tmp_path)
    table = read_csv(tmp_path / "report" / "moodle-grading-worksheet.csv")
    # Moodle's upload needs the Identifier, Grade and Last modified (grade) columns, by those names
    assert table[0] == MOODLE_COLUMNS
    assert {"Identifier", "Grade", "Last modified (grade)"} <= set(table[0])
    got = [dict(zip(table[0], line, strict=True)) for line in table[1:]]
    assert [(g["Identifier"], g["Full name"], g["Grade"], g["Maximum Grade"]) for g in got] == [
        ("Participant 100001", "Ada Adams", "11.00", "11.00"),
        ("Participant 100002", "Bo Li", "10.00", "11.00"),
        ("Participant 100003", "Cy Yang", "10.00", "11.00"),
    ]
    when = datetime.strptime(got[0]["Last modified (grade)"], "%A, %d %B %Y, %I:%M %p")
    assert before <= when <= datetime.now()
    assert got[2]["Feedback comments"] == "cornell: 10 of 10 (pass); whitted_aa: 0 of 1 (fail)"
    assert {g["Status"] for g in got} == {"Submitted for grading"} and {g["Grade can be changed"] for g in got} == {
        "Yes"
    }
    canvas = read_csv(tmp_path / "report" / "canvas-gradebook.csv")  # (tasks.json names a Canvas assignment)
    assert [line[:2] for line in canvas[2:]] == [["Ada Adams", ""], ["Bo Li", ""], ["Cy Yang", ""]]  # (no ids)


def test_moodle_s_time_is_written_as_moodle_writes_it():
    assert moodle_time(datetime(2024, 3, 5, 9, 5)) == "Tuesday, 5 March 2024, 9:05 AM"
    assert moodle_time(datetime(2024, 12, 15, 12, 30)) == "Sunday, 15 December 2024, 12:30 PM"
    assert moodle_time(datetime(2024, 1, 1, 0, 0)) == "Monday, 1 January 2024, 12:00 AM"


def test_late_work_is_marked_in_every_file_and_a_rerun_keeps_it(tmp_path, images):
    a_class(tmp_path, images, CANVAS)
    for _ in range(2):  # the second run resumes every grade
        rows = graded(tmp_path)
        report = tmp_path / "report"
        assert rows[("adamsada", "cornell")]["late"] is True and rows[("adamsada", "cornell")]["score"] == 7.5
        csv_rows = {
            (r["student"], r["task"]): r for r in csv.DictReader(io.StringIO((report / "report.csv").read_text()))
        }
        assert (csv_rows[("adamsada", "cornell")]["late"], csv_rows[("adamsada", "cornell")]["late_deducted"]) == (
            "True",
            "2.5",
        )
        book = {r["student"]: r for r in csv.DictReader(io.StringIO((report / "gradebook.csv").read_text()))}
        assert (book["adamsada"]["late"], book["adamsada"]["total"], book["libo"]["late"]) == (
            "cornell whitted_aa",
            "8.25",
            "",
        )
        page = (report / "index.html").read_text()
        assert '<th>adamsada <span class="late">late: cornell, whitted_aa</span></th>' in page
        assert '<span class="late">late −2.5</span>' in page and "the late policy took 2.5 of its points" in page
        results = json.loads((report / "gradescope" / "adamsada" / "results.json").read_text())
        assert results["score"] == 8.25
        assert results["tests"][0]["output"].endswith("\nLate: handed in late (the late policy took 2.5 of its points)")


def test_no_penalty_marks_late_work_and_keeps_its_score(tmp_path, images):
    a_class(tmp_path, images, CANVAS)
    (tmp_path / "tasks.json").write_text(json.dumps({"cornell": {"points": 10}}))
    rows = graded(tmp_path)
    assert (rows[("adamsada", "cornell")]["late"], rows[("adamsada", "cornell")]["score"]) == (True, 10.0)
    assert rows[("adamsada", "cornell")]["late_deducted"] == 0.0
    table = read_csv(tmp_path / "report" / "canvas-gradebook.csv")  # (Canvas students: a column per task)
    assert table[0][5:] == ["cornell", "whitted_aa"] and table[1][5:] == ["10", "1"]
    assert table[2] == ["adamsada", "12345", "", "", "", "10", "1"]


def test_a_task_of_its_own_assignment_has_its_own_column(tmp_path, images):
    a_class(tmp_path, images, CANVAS)
    tasks = {**TASKS, "whitted_aa": {"canvas": "Whitted extra (12399)", "points": 4}}
    (tmp_path / "tasks.json").write_text(json.dumps(tasks))
    graded(tmp_path)
    table = read_csv(tmp_path / "report" / "canvas-gradebook.csv")
    assert table[0][5:] == ["Homework 3 (12345)", "Whitted extra (12399)"] and table[1][5:] == ["10", "4"]
    assert table[4] == ["yangcy", "444", "", "", "", "10", "0"]


def test_the_option_names_the_assignment_and_a_misnamed_one_stops_the_run(tmp_path, images, capsys):
    from service.cli import main

    a_class(tmp_path, images, MOODLE)
    (tmp_path / "tasks.json").write_text("{}")
    args = ["grade-class", str(tmp_path / "scenes"), str(tmp_path / "subs"), "-o", str(tmp_path / "report"), "-q"]
    assert main([*args, "--canvas-assignment", "Homework 3 (12345)", "--no-diagnosis"]) == 0
    table = read_csv(tmp_path / "report" / "canvas-gradebook.csv")  # Moodle's students: no Canvas id
    assert table[0][5:] == ["Homework 3 (12345)"] and table[2] == ["Ada Adams", "", "", "", "", "2"]
    assert main([*args, "--canvas-assignment", "Homework 3"]) == 2
    assert "give the assignment as Canvas's gradebook names its column" in capsys.readouterr().err
    with pytest.raises(ClassError, match=r"tasks.json:1: \*.canvas: give the assignment"):
        (tmp_path / "tasks.json").write_text('{"*": {"canvas": "HW3"}}')
        graded(tmp_path)


def test_a_folder_of_both_exports_gives_each_lms_its_own_students(tmp_path, images):
    """Canvas's flat files and Moodle's folders in one submissions folder: the Moodle student is in Moodle's
    worksheet, not in Canvas's gradebook as a row with no id (which Canvas's import cannot match)."""
    a_class(
        tmp_path, images, {k: v for k, v in CANVAS.items() if k.startswith("libo")} | dict(list(MOODLE.items())[:2])
    )
    graded(tmp_path)
    canvas = read_csv(tmp_path / "report" / "canvas-gradebook.csv")
    assert [line[:2] for line in canvas[2:]] == [["libo", "222"]]
    moodle = read_csv(tmp_path / "report" / "moodle-grading-worksheet.csv")
    assert [line[:2] for line in moodle[1:]] == [["Participant 100001", "Ada Adams"]]
