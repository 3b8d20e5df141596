"""Grading a whole class: every status and reason, per-student scenes, reuse, atomic reports, the service."""

import csv
import json
import shutil

import numpy as np
import pytest

import schemas
import tracer
from helpers import scene_dict
from server import running_server
from service import classgrade
from service.cli import main


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
    scene, right), none (nothing), junk (not a PNG, wrong size), broken (an invalid own scene)."""
    root = tmp_path_factory.mktemp("class")
    scenes, subs = root / "scenes", root / "subs"
    scenes.mkdir()
    tasks = {"balls": small("01_three_spheres"), "lamps": small("02_all_lights")}
    for task, data in tasks.items():
        (scenes / f"{task}.json").write_text(json.dumps(data))
    (scenes / "README.txt").write_text("not a task")
    right = {task: rendered(data) for task, data in tasks.items()}

    def put(student, name, data):
        (subs / student).mkdir(parents=True, exist_ok=True)
        (subs / student / name).write_bytes(data if isinstance(data, bytes) else data.encode())

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
    put("own", "balls.json", json.dumps(own))
    put("own", "balls.png", own_png)
    put("own", "lamps.png", png(right["lamps"]))
    put("copycat", "balls.png", own_png)
    put("copycat", "lamps.png", png(right["lamps"]))
    (subs / "none").mkdir()
    put("junk", "balls.png", b"GIF89a not a png")
    put("junk", "lamps.png", png(right["lamps"][:10, :10]))
    put("junk", "essay.docx", b"?")
    broken = json.loads(json.dumps(tasks["lamps"]))
    next(o for o in broken["objects"] if o["type"] == "sphere")["radius"] = -1
    put("broken", "lamps.json", json.dumps(broken))
    put("broken", "lamps.png", png(right["lamps"]))
    put("broken", "balls.png", png(right["balls"]))
    return scenes, subs, root


def by_pair(rows):
    return {(r["student"], r["task"]): r for r in rows}


def cli_reason(capsys, scene, image):
    """What the single ``phongray grade`` says of this pair (after ``phongray: ``)."""
    code = main(["grade", str(scene), str(image)])
    err = capsys.readouterr().err.strip()
    assert code == 2
    return err.removeprefix("phongray: ")


def test_every_status_and_reason(klass, tmp_path, capsys):
    scenes, subs, _ = klass
    outcome = classgrade.grade_class(scenes, subs, tmp_path / "report", jobs=2)
    rows = by_pair(outcome.rows)
    assert len(outcome.rows) == 7 * 2  # every (student, task) pair, exactly once
    assert {k: r["status"] for k, r in rows.items()} == {
        ("bad", "balls"): "pass", ("bad", "lamps"): "fail", ("broken", "balls"): "pass",
        ("broken", "lamps"): "invalid", ("copycat", "balls"): "fail", ("copycat", "lamps"): "pass",
        ("good", "balls"): "pass", ("good", "lamps"): "pass", ("junk", "balls"): "invalid",
        ("junk", "lamps"): "invalid", ("none", "balls"): "missing", ("none", "lamps"): "missing",
        ("own", "balls"): "pass", ("own", "lamps"): "pass"}
    assert rows[("own", "balls")]["scene"] == "own" and rows[("copycat", "balls")]["scene"] == "shared"
    assert rows[("junk", "balls")]["reason"] == cli_reason(capsys, scenes / "balls.json", subs / "junk/balls.png")
    assert rows[("junk", "lamps")]["reason"] == cli_reason(capsys, scenes / "lamps.json", subs / "junk/lamps.png")
    assert rows[("broken", "lamps")]["reason"] == cli_reason(capsys, subs / "broken/lamps.json",
                                                            subs / "broken/lamps.png")
    assert ".radius: must be > 0" in rows[("broken", "lamps")]["reason"]
    assert rows[("none", "lamps")]["reason"] == "no lamps.png"
    assert sorted(outcome.ignored) == ["scenes/README.txt", "subs/junk/essay.docx"]
    assert rows[("bad", "lamps")]["fraction_off_nearby"] > 0.01 and rows[("good", "lamps")]["max_error"] == 0
    assert outcome.renders == 3  # two shared scenes and one student's own; the invalid one is not rendered


def test_the_report_files_agree_and_link_what_exists(klass, tmp_path):
    scenes, subs, _ = klass
    report = tmp_path / "report"
    outcome = classgrade.grade_class(scenes, subs, report, jobs=2)
    rows = json.loads((report / "report.json").read_text())
    assert rows == json.loads(json.dumps(outcome.rows))
    with open(report / "report.csv") as f:
        table = list(csv.DictReader(f))
    assert [(r["student"], r["task"], r["status"]) for r in table] == [(r["student"], r["task"], r["status"])
                                                                       for r in rows]
    assert list(table[0]) == classgrade.COLUMNS
    for r in rows:
        for key in ("reference", "submission", "heatmap"):
            if r[key]:
                assert (report / r[key]).is_file()
        assert (r["heatmap"] is not None) == (r["status"] in ("pass", "fail"))
    page = (report / "index.html").read_text()
    assert page.count('<td class="') == len(rows) and "4/7" in page and "3/7" in page
    assert page.rstrip().endswith("</html>")
    assert "http" not in page.replace("http-equiv", "")  # nothing from the network


def test_a_rerun_reuses_its_references_and_gives_the_same_report(klass, tmp_path):
    scenes, subs, _ = klass
    report = tmp_path / "report"
    first = classgrade.grade_class(scenes, subs, report, jobs=2)
    before = (report / "report.json").read_bytes()
    again = classgrade.grade_class(scenes, subs, report, jobs=2)
    assert first.renders == 3 and again.renders == 0
    assert (report / "report.json").read_bytes() == before


def test_an_interrupted_rerun_leaves_every_report_file_whole(klass, tmp_path, monkeypatch):
    scenes, subs, _ = klass
    report = tmp_path / "report"
    classgrade.grade_class(scenes, subs, report, jobs=2)
    real = classgrade.os.replace
    calls = []

    def replace(src, dst):
        calls.append(dst)
        if str(dst).endswith("report.csv"):
            raise KeyboardInterrupt  # Ctrl-C in the middle of writing the report
        real(src, dst)

    monkeypatch.setattr(classgrade.os, "replace", replace)
    with pytest.raises(KeyboardInterrupt):
        classgrade.grade_class(scenes, subs, report, jobs=2)
    monkeypatch.undo()
    assert len(json.loads((report / "report.json").read_text())) == 14
    with open(report / "report.csv") as f:
        assert len(list(csv.DictReader(f))) == 14
    assert (report / "index.html").read_text().rstrip().endswith("</html>")


def test_unusable_input_exits_2_with_one_line(tmp_path, capsys):
    (tmp_path / "scenes").mkdir()
    (tmp_path / "subs").mkdir()
    assert main(["grade-class", str(tmp_path / "scenes"), str(tmp_path / "subs"), "-o", str(tmp_path / "r")]) == 2
    assert capsys.readouterr().err.strip().count("\n") == 0
    assert main(["grade-class", str(tmp_path / "nowhere"), str(tmp_path / "subs"), "-o", str(tmp_path / "r")]) == 2
    assert "cannot read" in capsys.readouterr().err


def test_the_cli_prints_a_summary_and_exits_0_even_with_failures(klass, tmp_path, capsys):
    scenes, subs, _ = klass
    assert main(["grade-class", str(scenes), str(subs), "-o", str(tmp_path / "r"), "--jobs", "2"]) == 0
    out = capsys.readouterr().out
    assert "14 pairs: 7 passed, 2 failed, 2 missing, 3 invalid" in out


def test_the_same_grades_through_a_running_service(klass, tmp_path):
    scenes, subs, _ = klass
    local = by_pair(classgrade.grade_class(scenes, subs, tmp_path / "local", jobs=2).rows)
    with running_server(tmp_path, max_concurrent_renders="1") as (url, _):
        remote = classgrade.grade_class(scenes, subs, tmp_path / "remote", jobs=4, server=url)
    for key, row in by_pair(remote.rows).items():
        assert row["status"] == local[key]["status"], key
        assert row["fraction_off_nearby"] == local[key]["fraction_off_nearby"], key
        if row["status"] == "invalid":
            assert row["reason"] == local[key]["reason"], key
    shutil.rmtree(tmp_path / "remote")
