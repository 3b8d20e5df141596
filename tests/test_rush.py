"""A deadline rush on POST /grade against a real two-worker server (bench/rush.py, smaller): every student is
answered, with the right verdict, whatever the load (outcomes only: the bench keeps the times)."""

from __future__ import annotations

import json
from pathlib import Path

from bench.rush import HOMEWORK, make_class, rush, serving


def test_a_rush_on_grade_answers_every_student_with_the_right_verdict(tmp_path: Path):
    data = json.loads(HOMEWORK.read_text())
    data["image"].update(width=120, height=90)
    students = make_class(data, 20, seed=3, same=False)  # (14 exact, 3 honest offsets, 3 without shadows)
    assert {s.kind for s in students} == {"exact", "offset 1e-3", "no shadows"}
    # one render slot a worker, one thread a render: the students' own scenes' renders and the diagnoses of
    # the failing ones contend for the slots, as a class's do at a deadline on a larger server.  The outcome,
    # not the time, is asserted: a render may take as long as the client waits (at a load of ~15 a diagnosis
    # took longer than the default 120 s and was answered without one; the bench keeps the times)
    settings = {"max_concurrent_renders": "1", "render_threads": "1", "render_timeout": "3600"}
    with serving(2, settings, tmp_path / "server.log") as url:
        outcomes = rush(url, students, tries=20)
    wrong = [(o.student.name, o.student.kind, o.status, o.answer) for o in outcomes if not o.right]
    assert not wrong, wrong
    assert len(outcomes) == len(students)
    for o in outcomes:
        if o.student.kind == "offset 1e-3":  # (passed as the honest tracer's variant it is)
            words = o.answer["accepted"]
            assert words.startswith("a ray offset of ") and words.endswith(" along the normal"), o.answer
        assert "No diagnosis" not in json.dumps(o.answer)
    assert "Traceback" not in (tmp_path / "server.log").read_text()
