"""Students' folders as learning-management systems download them, and their files as untrusted input."""

import csv
import io
import json
import os
import stat

import numpy as np
import pytest
from PIL import Image

import schemas
import tracer
from service import classgrade
from service.classgrade import ClassRun
from service.classgrade.submissions import discover
from service.course.errors import ClassError
from service.course.untrusted import UntrustedFileError, read_untrusted

from helpers import scene_dict


@pytest.fixture(scope="module")
def task(tmp_path_factory):
    """One task, 'Cornell' (a capital letter, as TAs name things), and its right image."""
    root = tmp_path_factory.mktemp("lms")
    (root / "scenes").mkdir()
    data = scene_dict("01_three_spheres")
    data["image"].update(width=32, height=24)
    (root / "scenes" / "Cornell.json").write_text(json.dumps(data))
    return root, tracer.render_png(schemas.validate_scene(json.loads(json.dumps(data))))


def put(root, relative, data):
    path = root / "subs" / relative
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)
    return path


def rows_of(root, tmp_path):
    outcome = classgrade.grade_class(ClassRun(root / "scenes", root / "subs", tmp_path / "report", jobs=1))
    return {r["student"]: r for r in outcome.rows}, dict(outcome.ignored)


def jpeg(png: bytes) -> bytes:
    buf = io.BytesIO()
    Image.open(io.BytesIO(png)).save(buf, format="JPEG")
    return buf.getvalue()


def test_extensions_and_names_match_regardless_of_case_and_one_folder_deeper(task, tmp_path):
    right = task[1]
    root = tmp_path / "class"
    (root / "scenes").mkdir(parents=True)
    (root / "scenes" / "Cornell.json").write_bytes((task[0] / "scenes" / "Cornell.json").read_bytes())
    put(root, "ada/Cornell.PNG", right)
    put(root, "ben/cornell.png", right)
    put(root, "frank/hw3/Cornell.png", right)
    rows, ignored = rows_of(root, tmp_path)
    assert {s: (r["status"], r["file"]) for s, r in rows.items()} == {
        "ada": ("pass", "Cornell.PNG"),
        "ben": ("pass", "cornell.png"),
        "frank": ("pass", "hw3/Cornell.png"),
    }
    assert ignored == {}


def test_a_jpeg_is_invalid_not_missing(task, tmp_path):
    root, right = task
    root2 = tmp_path / "class"
    (root2 / "scenes").mkdir(parents=True)
    (root2 / "scenes" / "Cornell.json").write_bytes((root / "scenes" / "Cornell.json").read_bytes())
    put(root2, "cal/Cornell.jpg", jpeg(right))
    put(root2, "dee/Cornell.png", jpeg(right))  # a JPEG under a PNG's name
    put(root2, "eve/Cornell.gif", b"GIF89a....")
    rows, _ = rows_of(root2, tmp_path)
    assert rows["cal"]["status"] == "invalid"
    assert rows["cal"]["reason"] == f"{root2}/subs/cal/Cornell.jpg: image is a JPEG; PNG or PPM required"
    assert rows["dee"]["reason"] == f"{root2}/subs/dee/Cornell.png: image is a JPEG; PNG or PPM required"
    assert rows["eve"]["reason"].endswith("Cornell.gif: image is a GIF; PNG or PPM required")


def test_what_cannot_be_graded_is_reported_with_its_reason(task, tmp_path):
    root, right = task
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "Cornell.json").write_bytes((root / "scenes" / "Cornell.json").read_bytes())
    put(tmp_path, "two/a/Cornell.png", right)
    put(tmp_path, "two/b/Cornell.png", right)
    put(tmp_path, "both/Cornell.png", right)
    put(tmp_path, "both/old/Cornell.png", right)
    put(tmp_path, "png-and-jpg/Cornell.png", right)
    put(tmp_path, "png-and-jpg/Cornell.jpg", jpeg(right))
    put(tmp_path, "deep/hw/3/Cornell.png", right)
    put(tmp_path, "__MACOSX/deep/._Cornell.png", b"")
    put(tmp_path, "loose.png", right)
    put(tmp_path, "lnk/x.png", right)
    put(tmp_path, "cases/Cornell.png", right)  # (only the student knows which of two spellings is the one)
    put(tmp_path, "cases/cornell.png", right)
    os.symlink(tmp_path / "subs" / "both" / "Cornell.png", tmp_path / "subs" / "lnk" / "Cornell.png")
    rows, ignored = rows_of(tmp_path, tmp_path)
    subs = tmp_path / "subs"
    assert rows["two"]["status"] == "invalid"
    assert rows["two"]["reason"] == f"2 files for Cornell: {subs}/two/a/Cornell.png, {subs}/two/b/Cornell.png; keep one"
    assert rows["cases"]["status"] == "invalid"
    assert rows["cases"]["reason"] == (
        f"2 files for Cornell: {subs}/cases/Cornell.png, {subs}/cases/cornell.png; keep one"
    )
    assert rows["both"]["status"] == "pass" and rows["both"]["file"] == "Cornell.png"
    assert rows["png-and-jpg"]["status"] == "pass" and rows["png-and-jpg"]["file"] == "Cornell.png"
    assert rows["deep"]["status"] == "missing"
    assert rows["lnk"]["status"] == "invalid"
    assert rows["lnk"]["reason"] == f"{subs}/lnk/Cornell.png: a symbolic link; links in submissions are not followed"
    assert "__MACOSX" not in rows
    assert ignored == {
        f"{subs}/__MACOSX": "not a student's folder",
        f"{subs}/both/old/Cornell.png": f"another file for Cornell is graded: {subs}/both/Cornell.png",
        f"{subs}/png-and-jpg/Cornell.jpg": f"another file for Cornell is graded: {subs}/png-and-jpg/Cornell.png",
        f"{subs}/deep/hw/3": "a folder two levels down (phongray looks one folder deep)",
        f"{subs}/loose.png": "not in a student's folder",
        f"{subs}/lnk/x.png": "matches no task",
    }


def test_untrusted_files_are_read_bounded_and_never_through_links(tmp_path):
    (tmp_path / "big.png").write_bytes(b"x" * 101)
    assert read_untrusted(tmp_path / "big.png", 101) == b"x" * 101
    with pytest.raises(UntrustedFileError, match="larger than the limit max_image_bytes = 100 bytes"):
        read_untrusted(tmp_path / "big.png", 100)
    os.symlink(tmp_path / "big.png", tmp_path / "link.png")
    with pytest.raises(UntrustedFileError, match="a symbolic link"):
        read_untrusted(tmp_path / "link.png", 1000)
    os.mkfifo(tmp_path / "fifo.png")  # would block a plain read forever
    with pytest.raises(UntrustedFileError, match="not a regular file"):
        read_untrusted(tmp_path / "fifo.png", 1000)


def test_a_missing_folder_of_the_tas_is_a_class_error(tmp_path):
    with pytest.raises(ClassError, match="cannot read"):
        discover(tmp_path / "none", tmp_path)
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "t.json").write_text("{}")
    with pytest.raises(ClassError, match="cannot read"):
        discover(tmp_path / "scenes", tmp_path / "subs")


def test_a_student_with_an_own_scene_and_no_folder_is_missing(tmp_path):
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "t.json").write_text("{}")
    (tmp_path / "subs" / "ada").mkdir(parents=True)
    (tmp_path / "own" / "zoe").mkdir(parents=True)
    (tmp_path / "own" / "zoe" / "t.json").write_text("{}")
    batch = discover(tmp_path / "scenes", tmp_path / "subs", tmp_path / "own")
    ada, zoe = batch.pairs
    assert (zoe.student, zoe.own, zoe.image, zoe.scene) == ("zoe", True, None, tmp_path / "own" / "zoe" / "t.json")
    assert zoe.row == {"status": "missing", "reason": "no t.png"} and ada.student == "ada"


def test_the_pixels_of_a_nested_submission_are_graded(task, tmp_path):
    """Found one folder deeper is graded, not just found: a wrong image there fails."""
    root, right = task
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "Cornell.json").write_bytes((root / "scenes" / "Cornell.json").read_bytes())
    put(tmp_path, "gus/hw3/cornell.PNG", tracer.encode_png(np.zeros((24, 32, 3), np.uint8)))
    rows, _ = rows_of(tmp_path, tmp_path)
    assert rows["gus"]["status"] == "fail" and rows["gus"]["file"] == "hw3/cornell.PNG"


@pytest.mark.skipif(os.geteuid() != 0, reason="making a device node needs root (as a tar extracted by root does)")
def test_a_device_or_fifo_is_looked_at_and_never_opened(tmp_path, monkeypatch):
    os.mknod(tmp_path / "zero.png", 0o666 | stat.S_IFCHR, os.makedev(1, 5))  # /dev/zero: a read never ends
    os.mkfifo(tmp_path / "fifo.png")
    opened = []
    real_open = os.open
    monkeypatch.setattr(os, "open", lambda path, *a, **kw: opened.append(path) or real_open(path, *a, **kw))
    with pytest.raises(UntrustedFileError, match="^a device, not a regular file$"):
        read_untrusted(tmp_path / "zero.png", 1000)
    with pytest.raises(UntrustedFileError, match="^a FIFO, not a regular file$"):
        read_untrusted(tmp_path / "fifo.png", 1000)
    assert opened == []


# -- learning-management systems' exports, as they come -----------------------------------------------------


def with_task(task, tmp_path):
    """A class folder of the task's scene alone (tmp_path/scenes), to put submissions in (tmp_path/subs)."""
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "Cornell.json").write_bytes((task[0] / "scenes" / "Cornell.json").read_bytes())
    return task[1]


def test_a_canvas_flat_folder_is_graded_under_the_students_logins(task, tmp_path):
    right = with_task(task, tmp_path)
    put(tmp_path, "adamsada_LATE_12345_67890_cornell-1.png", right)
    put(tmp_path, "bobbybee_222_333_Cornell.png", right)
    put(tmp_path, "carlc_late_444_555_Cornell (1).PNG", tracer.encode_png(np.zeros((24, 32, 3), np.uint8)))
    put(tmp_path, "readme.txt", b"exported by Canvas")
    rows, ignored = rows_of(tmp_path, tmp_path)
    assert {s: (r["status"], r["file"]) for s, r in rows.items()} == {
        "adamsada": ("pass", "adamsada_LATE_12345_67890_cornell-1.png"),
        "bobbybee": ("pass", "bobbybee_222_333_Cornell.png"),
        "carlc": ("fail", "carlc_late_444_555_Cornell (1).PNG"),
    }
    assert ignored == {f"{tmp_path}/subs/readme.txt": "not in a student's folder"}
    assert {s: r["lms_id"] for s, r in rows.items()} == {"adamsada": "12345", "bobbybee": "222", "carlc": "444"}
    with open(tmp_path / "report" / "gradebook.csv", newline="") as f:
        assert [r[:2] for r in csv.reader(f)] == [
            ["student", "id"],
            ["adamsada", "12345"],
            ["bobbybee", "222"],
            ["carlc", "444"],
        ]


def test_moodle_folders_are_graded_under_the_students_names(task, tmp_path):
    right = with_task(task, tmp_path)
    put(tmp_path, "Ada Adams_123456_assignsubmission_file_/Cornell.png", right)
    put(tmp_path, "Ada Adams_123456_assignsubmission_onlinetext_/onlinetext.html", b"<p>hi</p>")
    put(tmp_path, "Bo Li_17_assignsubmission_file_/hw/cornell.png", right)
    put(tmp_path, "Bo Li_18_assignsubmission_file_/Cornell.jpg", jpeg(right))  # another Bo Li
    put(tmp_path, "Cy Ng_19_assignsubmission_file_Cornell.png", right)  # downloaded without folders
    put(tmp_path, ".._20_assignsubmission_file_/Cornell.png", right)  # never a student named ".."
    rows, ignored = rows_of(tmp_path, tmp_path)
    assert {s: (r["status"], r["file"]) for s, r in rows.items()} == {
        "Ada Adams": ("pass", "Cornell.png"),
        "Bo Li (17)": ("pass", "hw/cornell.png"),
        "Bo Li (18)": ("invalid", "Cornell.jpg"),
        "Cy Ng": ("pass", "Cy Ng_19_assignsubmission_file_Cornell.png"),
    }
    subs = tmp_path / "subs"
    assert ignored == {
        f"{subs}/Ada Adams_123456_assignsubmission_onlinetext_/onlinetext.html": "matches no task",
        f"{subs}/.._20_assignsubmission_file_": "not a student's folder",
    }
    assert (tmp_path / "report" / "gradescope" / "Ada Adams" / "results.json").is_file()
    assert {s: r["lms_id"] for s, r in rows.items()} == {
        "Ada Adams": "123456",
        "Bo Li (17)": "17",
        "Bo Li (18)": "18",
        "Cy Ng": "19",
    }


def test_a_resubmission_and_a_near_miss_of_the_tasks_name(task, tmp_path):
    right = with_task(task, tmp_path)
    put(tmp_path, "ada/Cornell (2).png", right)
    put(tmp_path, "ben/cornel.png", right)
    put(tmp_path, "cal/Cornell.png", right)
    put(tmp_path, "cal/Cornell-1.png", right)  # which one is the newer? the student says, not phongray
    rows, ignored = rows_of(tmp_path, tmp_path)
    subs = tmp_path / "subs"
    assert rows["ada"]["status"] == "pass" and rows["ada"]["file"] == "Cornell (2).png"
    assert rows["ben"]["status"] == "missing"
    assert rows["ben"]["reason"] == "no Cornell.png (found cornel.png: did you mean Cornell.png?)"
    assert ignored == {f"{subs}/ben/cornel.png": "matches no task (did you mean Cornell?)"}
    assert rows["cal"]["reason"] == f"2 files for Cornell: {subs}/cal/Cornell-1.png, {subs}/cal/Cornell.png; keep one"


def test_a_submissions_folder_of_no_student_stops_the_run_saying_what_was_expected(task, tmp_path, capsys):
    from service.cli import main

    right = with_task(task, tmp_path)
    put(tmp_path, "Cornell.png", right)  # a loose file: no student's
    put(tmp_path, "__MACOSX/._Cornell.png", b"")
    assert main(["grade-class", str(tmp_path / "scenes"), str(tmp_path / "subs"), "-o", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(
        f"phongray: {tmp_path}/subs: no student found; expected a "
        f"folder per student (<student>/<task>.png), Moodle's folders"
    )
    assert "Canvas's flat folder (<login>_<id>_<id>_<task>.png)" in err and not (tmp_path / "r").exists()


def test_a_report_folder_inside_the_submissions_folder_stops_the_run(task, tmp_path, capsys):
    from service.cli import main

    right = with_task(task, tmp_path)
    put(tmp_path, "ada/Cornell.png", right)
    for inside in (tmp_path / "subs" / "report", tmp_path / "subs" / "ada" / "report", tmp_path / "subs"):
        assert main(["grade-class", str(tmp_path / "scenes"), str(tmp_path / "subs"), "-o", str(inside)]) == 2
        err = capsys.readouterr().err
        assert err == (
            f"phongray: {inside}: the report folder is inside the submissions folder {tmp_path}/subs "
            f"(it would be graded as a student's); write it elsewhere\n"
        )
    assert sorted(os.listdir(tmp_path / "subs")) == ["ada"] and os.listdir(tmp_path / "subs" / "ada") == ["Cornell.png"]
    # nor the submissions where the report writes its own copies of them (a TA's hw3/submissions and -o hw3)
    hw3 = tmp_path / "hw3"
    (hw3 / "submissions" / "ada").mkdir(parents=True)
    (hw3 / "submissions" / "ada" / "Cornell.png").write_bytes(right)
    assert main(["grade-class", str(tmp_path / "scenes"), str(hw3 / "submissions"), "-o", str(hw3)]) == 2
    assert capsys.readouterr().err == (
        f"phongray: {hw3}: the report writes its submissions/ folder where the submissions folder "
        f"{hw3}/submissions is (its files would be graded as the students'); write it elsewhere\n"
    )
    assert os.listdir(hw3) == ["submissions"]


def test_a_student_folder_swapped_for_a_link_while_the_references_render_is_not_followed(task, tmp_path):
    """eve's folder becomes a link to ada's (right) images once the class is found: eve's own image is graded."""
    right = with_task(task, tmp_path)
    put(tmp_path, "ada/Cornell.png", right)
    put(tmp_path, "eve/Cornell.png", tracer.encode_png(np.zeros((24, 32, 3), np.uint8)))
    subs = tmp_path / "subs"
    swapped = []

    def swap(done: int, total: int) -> None:
        if not swapped:  # the first tick: the class is found, nothing is rendered yet
            os.rename(subs / "eve", tmp_path / "eve-was")
            os.symlink("ada", subs / "eve")
            swapped.append(True)

    outcome = classgrade.grade_class(ClassRun(tmp_path / "scenes", subs, tmp_path / "report", jobs=1), progress=swap)
    rows = {r["student"]: r for r in outcome.rows}
    assert swapped and rows["eve"]["status"] == "fail" and rows["ada"]["status"] == "pass"
    assert (tmp_path / "report" / "submissions" / "eve" / "Cornell.png").read_bytes() != right


def test_a_tasks_own_name_comes_before_a_resubmissions_suffix():
    from service.course.lms import TaskNames

    names = TaskNames(["Cornell", "cornell-2", "box"])
    assert [
        (n.task, n.exact)
        for n in map(
            names.match,
            ["cornell-2.png", "Cornell-3.PNG", "box (12).png", "BOX-1.jpg", "box-x.png", "box (1).png.json"],
        )
    ] == [("cornell-2", True), ("Cornell", True), ("box", True), ("box", False), (None, False), (None, False)]
    assert names.near("cornel.PNG") == "Cornell"
    assert names.near("Box-2-final.png") is None and names.near("notes.txt") is None


def test_a_name_spelt_decomposed_is_the_same_student_as_the_tas_composed_one(tmp_path):
    """An archive unpacked on a Mac spells José decomposed (NFD), the TA's student-scenes folder composed (NFC):
    one student, graded against their own scene, never a second José with nothing sent."""
    import unicodedata

    nfd, nfc = (unicodedata.normalize(form, "José García") for form in ("NFD", "NFC"))
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "Cornell.json").write_text("{}")
    put(tmp_path, f"{nfd}_555_assignsubmission_file_/Cornell.png", b"png")
    put(tmp_path, f"{nfd}ez/Cornell.png", b"png")  # (a folder per student, too: Joséez)
    (tmp_path / "own" / nfc).mkdir(parents=True)
    (tmp_path / "own" / nfc / "Cornell.json").write_text("{}")
    (tmp_path / "own" / f"{nfc}ez").mkdir(parents=True)
    (tmp_path / "own" / f"{nfc}ez" / "Cornell.json").write_text("{}")
    batch = discover(tmp_path / "scenes", tmp_path / "subs", tmp_path / "own")
    assert [(p.student, p.own, p.file, p.row, p.lms_id) for p in batch.pairs] == [
        (nfc, True, "Cornell.png", {}, "555"),
        (f"{nfc}ez", True, "Cornell.png", {}, ""),
    ]


@pytest.mark.parametrize(
    "folder, meant",
    [
        ("ADA", "ada"),  # another case
        ("Eve Ng_777_assignsubmission_file_", "Eve Ng"),  # Moodle's folder name
        ("Bo Li", "Bo Li (17) or Bo Li (18)"),  # without the id that tells two students apart
        ("Eve Ng (777)", "Eve Ng"),  # with an id that one Eve Ng does not need
    ],
)
def test_student_scenes_under_another_name_than_the_students_stop_the_run(tmp_path, folder, meant):
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "Cornell.json").write_text("{}")
    for student in (
        "ada",
        "Eve Ng_777_assignsubmission_file_",
        "Bo Li_17_assignsubmission_file_",
        "Bo Li_18_assignsubmission_file_",
    ):
        put(tmp_path, f"{student}/Cornell.png", b"png")
    (tmp_path / "own" / folder).mkdir(parents=True)
    (tmp_path / "own" / folder / "Cornell.json").write_text("{}")
    with pytest.raises(ClassError) as caught:
        discover(tmp_path / "scenes", tmp_path / "subs", tmp_path / "own")
    assert str(caught.value).startswith(
        f"{tmp_path}/own/{folder}: no student {folder} among the submissions (did you mean {meant}?"
    )
    # a student of their own scene who sent nothing is no mistake: missing
    (tmp_path / "own" / folder).rename(tmp_path / "own" / "zed")
    batch = discover(tmp_path / "scenes", tmp_path / "subs", tmp_path / "own")
    assert [(p.own, p.row["status"]) for p in batch.pairs if p.student == "zed"] == [(True, "missing")]


def test_a_name_a_student_gave_themselves_never_makes_them_another_student(tmp_path):
    """Moodle lets a student edit their own name: 'Bo Li_17_assignsubmission_file_' or 'Bo Li (17)' names a
    second student, never the first Bo Li, whose image stays theirs alone (not '2 files; keep one')."""
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "Cornell.json").write_text("{}")
    for folder, data in [
        ("Bo Li_17_assignsubmission_file_", b"bo"),
        ("Bo Li_18_assignsubmission_file_", b"other"),
        ("Bo Li_17_assignsubmission_file__66_assignsubmission_file_", b"mallory"),
        ("Bo Li (17)_99_assignsubmission_file_", b"trudy"),
    ]:
        put(tmp_path, f"{folder}/Cornell.png", data)
    batch = discover(tmp_path / "scenes", tmp_path / "subs")
    assert {p.student: (p.lms_id, p.data, p.row) for p in batch.pairs} == {
        "Bo Li (17)": ("17", b"bo", {}),
        "Bo Li (18)": ("18", b"other", {}),
        "Bo Li_17_assignsubmission_file_": ("66", b"mallory", {}),
        "Bo Li (17) (99)": ("99", b"trudy", {}),
    }


def test_the_files_a_macs_archive_leaves_in_the_tas_folders_are_ignored(tmp_path):
    """A class folder zipped on a Mac and unpacked elsewhere holds ._Cornell.json (AppleDouble, binary) beside
    each file, .DS_Store and __MACOSX/: never a task or a student's scene, so no reason to stop the run."""
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "Cornell.json").write_text("{}")
    for junk in (
        "scenes/._Cornell.json",
        "scenes/.DS_Store",
        "own/.DS_Store",
        "own/ada/._Cornell.json",
        "own/__MACOSX/ada/._Cornell.json",
    ):
        (tmp_path / junk).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / junk).write_bytes(b"\x00\x05\x16\x07")
    (tmp_path / "own" / "ada" / "Cornell.json").write_text("{}")
    put(tmp_path, "ada/Cornell.png", b"png")
    batch = discover(tmp_path / "scenes", tmp_path / "subs", tmp_path / "own")
    assert list(batch.tasks) == ["Cornell"] and [(p.student, p.own) for p in batch.pairs] == [("ada", True)]
    assert sorted(dict(batch.ignored)) == [
        f"{tmp_path}/{junk}"
        for junk in (
            "own/.DS_Store",
            "own/__MACOSX",
            "own/ada/._Cornell.json",
            "scenes/.DS_Store",
            "scenes/._Cornell.json",
        )
    ]


def test_a_report_folder_that_is_the_scenes_folder_or_in_the_student_scenes_stops_the_run(task, tmp_path, capsys):
    """Its report.json would be a task, or its gradescope/ folder a student of their own scenes, next time."""
    from service.cli import main

    right = with_task(task, tmp_path)
    put(tmp_path, "ada/Cornell.png", right)
    (tmp_path / "own" / "ada").mkdir(parents=True)
    common = [
        "grade-class",
        str(tmp_path / "scenes"),
        str(tmp_path / "subs"),
        "--student-scenes",
        str(tmp_path / "own"),
        "-o",
    ]
    assert main([*common, str(tmp_path / "scenes")]) == 2
    assert capsys.readouterr().err == (
        f"phongray: {tmp_path}/scenes: the report folder is the scenes folder (its "
        f"report.json would be read as a task); write it elsewhere\n"
    )
    for inside in (tmp_path / "own", tmp_path / "own" / "report"):
        assert main([*common, str(inside)]) == 2
        assert capsys.readouterr().err == (
            f"phongray: {inside}: the report folder is inside the --student-scenes folder {tmp_path}/own (it would "
            f"be read as a student's scenes); write it elsewhere\n"
        )
    assert sorted(os.listdir(tmp_path / "scenes")) == ["Cornell.json"] and os.listdir(tmp_path / "own") == ["ada"]


@pytest.mark.parametrize(
    "layout, files",
    [
        ("an LMS's export", ["Ada Adams_1_assignsubmission_file_/Cornell.png", "Bo Li_2_assignsubmission_file_/x.png"]),
        ("an LMS's export", ["adamsada_LATE_1_7_Cornell.png", "libo_2_8_Cornell-1.png"]),
        ("a folder per student", ["ada/Cornell.png", "bo/cornell.PNG", "cy/notes.txt"]),
    ],
)
def test_a_class_unpacked_into_a_folder_of_its_own_stops_the_run(tmp_path, capsys, layout, files):
    """The TA gave the folder an export was unpacked into: one 'student' with every image '2 files; keep one' or
    missing would be graded; the run stops, naming the folder to give."""
    from service.cli import main

    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "Cornell.json").write_text("{}")
    for file in files:
        put(tmp_path, f"hw3/{file}", b"png")
    assert main(["grade-class", str(tmp_path / "scenes"), str(tmp_path / "subs"), "-o", str(tmp_path / "r")]) == 2
    assert capsys.readouterr().err == (
        f"phongray: {tmp_path}/subs: its one folder, hw3, holds the submissions of "
        f"several students ({layout}): give {tmp_path}/subs/hw3 as the submissions "
        f"folder\n"
    )
    assert not (tmp_path / "r").exists()


def test_a_class_of_one_student_with_a_folder_deeper_is_graded(tmp_path):
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "Cornell.json").write_text("{}")
    (tmp_path / "scenes" / "box.json").write_text("{}")
    put(tmp_path, "ada/hw3/Cornell.png", b"png")
    put(tmp_path, "ada/part2/box.png", b"box")
    put(tmp_path, "ada/old/notes.png", b"png")
    batch = discover(tmp_path / "scenes", tmp_path / "subs")
    assert [(p.student, p.file, p.data) for p in batch.pairs] == [
        ("ada", "hw3/Cornell.png", b"png"),
        ("ada", "part2/box.png", b"box"),
    ]
    # one Moodle student's draft/ and final/: that student's two files, not a class
    (tmp_path / "subs" / "ada").rename(tmp_path / "subs" / "Ada Adams_1_assignsubmission_file_")
    put(tmp_path, "Ada Adams_1_assignsubmission_file_/old/Cornell.png", b"old")
    batch = discover(tmp_path / "scenes", tmp_path / "subs")
    assert [(p.student, p.row.get("status")) for p in batch.pairs] == [("Ada Adams", "invalid"), ("Ada Adams", None)]
    assert batch.pairs[0].row["reason"].startswith("2 files for Cornell: ")


def test_a_file_name_spelt_decomposed_is_the_tasks():
    """A Mac's archive spells café.png decomposed (NFD); the TA's scene café.json is composed (NFC)."""
    import unicodedata

    from service.course.lms import TaskNames

    nfc, nfd = (unicodedata.normalize(form, "café") for form in ("NFC", "NFD"))
    names = TaskNames([nfc, "box"])
    assert [(n.task, n.exact) for n in map(names.match, [f"{nfd}.png", f"{nfd.upper()}-1.PNG", "box.png"])] == [
        (nfc, True),
        (nfc, False),
        ("box", True),
    ]
    assert TaskNames([nfd]).match(f"{nfc}.png").task == nfd and names.near(f"{nfd}s.png") == nfc


def test_two_students_whose_names_differ_only_in_case_are_told_apart_by_their_ids(tmp_path):
    """On a Mac's or Windows's file system the report's folders of 'Ada Adams' and 'ada adams' are one: each
    would overwrite the other's results.json, heat-maps and copies."""
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "Cornell.json").write_text("{}")
    put(tmp_path, "Ada Adams_1_assignsubmission_file_/Cornell.png", b"first")
    put(tmp_path, "ada adams_2_assignsubmission_file_/Cornell.png", b"second")
    put(tmp_path, "Bo Li_3_assignsubmission_file_/Cornell.png", b"third")
    batch = discover(tmp_path / "scenes", tmp_path / "subs")
    assert {p.student: p.data for p in batch.pairs} == {
        "Ada Adams (1)": b"first",
        "ada adams (2)": b"second",
        "Bo Li": b"third",
    }


def test_a_resubmitted_copy_of_a_download_is_its_tasks():
    """A browser saved 'Spheres (1).png' and Canvas added its '-1' on a resubmission: 'Spheres (1)-1.png'."""
    from service.course.lms import TaskNames

    names = TaskNames(["spheres", "cornell-3", "cornell"])
    assert [
        names.match(n).task
        for n in ["Spheres (1)-1.png", "spheres-2 (3).PNG", "cornell-3-1.png", "cornell-4-1.png", "spheres-x-1.png"]
    ] == ["spheres", "spheres", "cornell-3", "cornell", None]
    assert names.near("sphere (1)-2.png") == "spheres"
