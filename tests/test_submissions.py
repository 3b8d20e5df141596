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
from service.submissions import ClassError, UntrustedFileError, discover, read_untrusted

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
    outcome = classgrade.grade_class(root / "scenes", root / "subs", tmp_path / "report", jobs=1)
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
        "ada": ("pass", "Cornell.PNG"), "ben": ("pass", "cornell.png"), "frank": ("pass", "hw3/Cornell.png")}
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
    assert rows["cal"]["reason"] == f"{root2}/subs/cal/Cornell.jpg: image is a JPEG; PNG required"
    assert rows["dee"]["reason"] == f"{root2}/subs/dee/Cornell.png: image is a JPEG; PNG required"
    assert rows["eve"]["reason"].endswith("Cornell.gif: image is a GIF; PNG required")


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
    os.symlink(tmp_path / "subs" / "both" / "Cornell.png", tmp_path / "subs" / "lnk" / "Cornell.png")
    rows, ignored = rows_of(tmp_path, tmp_path)
    subs = tmp_path / "subs"
    assert rows["two"]["status"] == "invalid"
    assert rows["two"]["reason"] == f"2 files for Cornell: {subs}/two/a/Cornell.png, {subs}/two/b/Cornell.png; keep one"
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
        f"{subs}/lnk/x.png": "matches no task"}


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
        "carlc": ("fail", "carlc_late_444_555_Cornell (1).PNG")}
    assert ignored == {f"{tmp_path}/subs/readme.txt": "not in a student's folder"}
    assert {s: r["lms_id"] for s, r in rows.items()} == {"adamsada": "12345", "bobbybee": "222", "carlc": "444"}
    with open(tmp_path / "report" / "gradebook.csv", newline="") as f:
        assert [r[:2] for r in csv.reader(f)] == [["student", "id"], ["adamsada", "12345"], ["bobbybee", "222"],
                                                  ["carlc", "444"]]


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
        "Ada Adams": ("pass", "Cornell.png"), "Bo Li (17)": ("pass", "hw/cornell.png"),
        "Bo Li (18)": ("invalid", "Cornell.jpg"), "Cy Ng": ("pass", "Cy Ng_19_assignsubmission_file_Cornell.png")}
    subs = tmp_path / "subs"
    assert ignored == {f"{subs}/Ada Adams_123456_assignsubmission_onlinetext_/onlinetext.html": "matches no task",
                       f"{subs}/.._20_assignsubmission_file_": "not a student's folder"}
    assert (tmp_path / "report" / "gradescope" / "Ada Adams" / "results.json").is_file()
    assert {s: r["lms_id"] for s, r in rows.items()} == {"Ada Adams": "123456", "Bo Li (17)": "17",
                                                         "Bo Li (18)": "18", "Cy Ng": "19"}


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
    assert err.count("\n") == 1 and err.startswith(f"phongray: {tmp_path}/subs: no student found; expected a "
                                                   f"folder per student (<student>/<task>.png), Moodle's folders")
    assert "Canvas's flat folder (<login>_<id>_<id>_<task>.png)" in err and not (tmp_path / "r").exists()


def test_a_report_folder_inside_the_submissions_folder_stops_the_run(task, tmp_path, capsys):
    from service.cli import main

    right = with_task(task, tmp_path)
    put(tmp_path, "ada/Cornell.png", right)
    for inside in (tmp_path / "subs" / "report", tmp_path / "subs" / "ada" / "report", tmp_path / "subs"):
        assert main(["grade-class", str(tmp_path / "scenes"), str(tmp_path / "subs"), "-o", str(inside)]) == 2
        err = capsys.readouterr().err
        assert err == (f"phongray: {inside}: the report folder is inside the submissions folder {tmp_path}/subs "
                       f"(it would be graded as a student's); write it elsewhere\n")
    assert sorted(os.listdir(tmp_path / "subs")) == ["ada"] and os.listdir(tmp_path / "subs" / "ada") == ["Cornell.png"]
    # nor the submissions where the report writes its own copies of them (a TA's hw3/submissions and -o hw3)
    hw3 = tmp_path / "hw3"
    (hw3 / "submissions" / "ada").mkdir(parents=True)
    (hw3 / "submissions" / "ada" / "Cornell.png").write_bytes(right)
    assert main(["grade-class", str(tmp_path / "scenes"), str(hw3 / "submissions"), "-o", str(hw3)]) == 2
    assert capsys.readouterr().err == (
        f"phongray: {hw3}: the report writes its submissions/ folder where the submissions folder "
        f"{hw3}/submissions is (its files would be graded as the students'); write it elsewhere\n")
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

    outcome = classgrade.grade_class(tmp_path / "scenes", subs, tmp_path / "report", jobs=1, progress=swap)
    rows = {r["student"]: r for r in outcome.rows}
    assert swapped and rows["eve"]["status"] == "fail" and rows["ada"]["status"] == "pass"
    assert (tmp_path / "report" / "submissions" / "eve" / "Cornell.png").read_bytes() != right


def test_a_tasks_own_name_comes_before_a_resubmissions_suffix():
    from service.lms import TaskNames

    names = TaskNames(["Cornell", "cornell-2", "box"])
    assert [(n.task, n.exact) for n in map(names.match, ["cornell-2.png", "Cornell-3.PNG", "box (12).png",
                                                          "BOX-1.jpg", "box-x.png", "box (1).png.json"])] == [
        ("cornell-2", True), ("Cornell", True), ("box", True), ("box", False), (None, False), (None, False)]
    assert names.near("cornel.PNG") == "Cornell"
    assert names.near("Box-2-final.png") is None and names.near("notes.txt") is None
