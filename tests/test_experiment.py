"""Diagnosis by experiment (service.programs.experiment): a buggy program asked its task's probes in the
sandbox, its answers put in sentences; an honest one answers every probe right.  The programs are
tests/programs/tracer.py with one mistake switched on."""

import json
import struct
import zlib
from collections.abc import Callable
from pathlib import Path

import pytest

from service.classgrade.job import Program, _runner
from service.classgrade.tasks import grade_task
from service.diagnosis.records import matched
from service.programs import Limits, check_sandbox
from service.programs.experiment import Thresholds, experiment, render_png
from service.programs.outcome import Reason, RunOutcome
from service.programs.probes import Kind
from tracer.image import PNG_SIGNATURE, png_chunk

HERE = Path(__file__).parent / "programs"
LIMITS = Limits(wall_seconds=30.0, cpu_seconds=30, memory_bytes=1 << 30, output_bytes=1 << 20, folder_bytes=1 << 20)


def student(tmp_path: Path, mistake: str) -> Path:
    """A student's folder: the tracer and its mistakes.txt."""
    folder = tmp_path / (mistake.replace("\n", "-") or "honest")
    folder.mkdir()
    (folder / "tracer.py").write_text((HERE / "tracer.py").read_text())
    (folder / "mistakes.txt").write_text(mistake)
    return folder


def graded(tmp_path: Path, mistake: str, task: str):
    """A student's program run on its task's scene, and the task's own grade of its image: (the scene, the
    runner, the image, the diagnosis as its answer gives it, or None)."""
    check_sandbox()
    run = _runner(
        student(tmp_path, mistake), Program("python3 tracer.py {scene} {output}", limits=LIMITS), f"{task}.json"
    )
    scene = (HERE / f"{task}.json").read_bytes()
    first = run(scene)
    assert first.ok, first.detail
    graded = grade_task(render_png(json.loads(scene)), first.image, 2.0, 0.001, scene)
    found = None if graded.graded is None or graded.graded.diagnosis is None else graded.graded.diagnosis.as_dict()
    return scene, run, first.image, found


def asked(tmp_path: Path, mistake: str, task: str, diagnosed: bool = True):
    """The experiment as a failing pair's grade asks it: the task's own diagnosis's exact match kept out (none
    when not ``diagnosed``: as a grade that found no exact match asks it)."""
    scene, run, image, found = graded(tmp_path, mistake, task)
    known = tuple(matched(found)[:1]) if diagnosed else ()
    return experiment(scene, image, run, Thresholds(2.0, 0.001), known)


def test_a_spot_without_its_ramp_is_wrong_between_its_inner_and_outer_cone(tmp_path):
    found = asked(tmp_path, "spot-hard-edge", "spot")
    assert found.sentences[0] == "your spot light 'key' is wrong between its inner and outer cone"
    assert "alone, your point light 'fill' is right" in found.sentences


def test_glass_left_out_is_refraction_missing_with_reflection_right(tmp_path):
    found = asked(tmp_path, "no-refraction", "glass")
    assert found.sentences == ["reflection right, refraction missing"]


@pytest.mark.parametrize("task", ["spot", "lamps"])
def test_no_shadows_found_by_the_diagnosis_is_kept_out_and_no_light_is_blamed(tmp_path, task):
    """The task's diagnosis names no shadow rays: the probes' references are rendered without them too, so a
    light (or the glass) the program gets right is not told wrong for the shadows."""
    found = asked(tmp_path, "no-shadows", task)
    assert [a.verdict for a in found.answers] == ["right"] * len(found.answers)
    assert found.sentences == []


def test_refraction_missing_is_not_blamed_on_the_lights(tmp_path):
    """Everything but refraction: the lights' probes are made without the glass, and both lights are right."""
    found = asked(tmp_path, "no-refraction", "lamps")
    assert found.sentences == ["refraction missing"]
    lights = {a.probe.name: a.verdict for a in found.answers if a.probe.kind is Kind.LIGHT}
    assert lights == {"spot light 'key' alone": "right", "point light 'fill' alone": "right"}
    assert all(
        a.probe.scene["materials"]["glass"]["transmittance"] == 0 for a in found.answers if a.probe.kind is Kind.LIGHT
    )


@pytest.mark.parametrize("task", ["lamps", "glass"])
def test_refraction_missing_and_no_shadows_are_both_found(tmp_path, task):
    """Two mistakes: the task's own diagnosis names both, made together (and no third the image cannot tell from
    one of them); with that match kept out, the probes find nothing more behind it.  Asked as a grade that found
    no match asks it, the glass is found missing (the task's image is the program's own image without it), and
    its image without the glass, diagnosed, shows no shadow rays; no light, diffuse or specular is blamed."""
    (tmp_path / "as-graded").mkdir()
    names = matched(graded(tmp_path / "as-graded", "no-refraction\nno-shadows", task)[3])
    assert [sorted(n.split("+")) for n in names] == [["no-refraction", "no-shadows"]]
    (tmp_path / "kept-out").mkdir()
    assert asked(tmp_path / "kept-out", "no-refraction\nno-shadows", task).found == ()
    found = asked(tmp_path, "no-refraction\nno-shadows", task, diagnosed=False)
    assert found.sentences[:2] == ["refraction missing", "no shadow rays (seen with the glass left out)"]
    assert found.found == ("no-shadows",)
    assert not any("light" in s or "diffuse" in s or "specular" in s for s in found.sentences)


@pytest.mark.parametrize("task", ["spot", "lamps"])
def test_no_shadows_and_a_spot_without_its_ramp_are_both_found(tmp_path, task):
    """Every light is wrong (no shadows), so one alone (the point light) is diagnosed: no shadow rays; judged
    again without shadows, the point light is right and the spot is wrong in its ramp alone."""
    found = asked(tmp_path, "no-shadows\nspot-hard-edge", task)
    assert found.sentences[-3:] == [
        "no shadow rays (seen with the point light 'fill' alone)",
        "your spot light 'key' is wrong between its inner and outer cone",
        "alone, your point light 'fill' is right",
    ]
    assert found.found == ("no-shadows",)


def fake_program(answer: bytes) -> Callable[[bytes], RunOutcome]:
    """A program (no sandbox: its answers are made here) that renders every scene without shadows, but for a
    scene with one light, which it answers with ``answer``."""

    def run(scene: bytes) -> RunOutcome:
        parsed = json.loads(scene)
        if len(parsed["lights"]) == 1:
            return RunOutcome(Reason.OK, "ok", answer)
        return RunOutcome(Reason.OK, "ok", render_png(parsed, ("no-shadows",)))

    return run


def bomb(side: int) -> bytes:
    """A PNG of ``side``² one-bit pixels: a few tens of kilobytes that would decode to hundreds of megabytes."""
    row = b"\0" * (1 + (side + 7) // 8)
    header = struct.pack(">IIBBBBB", side, side, 1, 0, 0, 0, 0)
    return (
        PNG_SIGNATURE
        + png_chunk(b"IHDR", header)
        + png_chunk(b"IDAT", zlib.compress(row * side, 9))
        + png_chunk(b"IEND", b"")
    )


@pytest.mark.parametrize("answer", [b"this is not a PNG at all", "bomb"])
def test_a_probe_answered_with_what_is_not_its_image_is_that_probes_no_answer(answer):
    """Not a PNG, or a 13000² PNG of 20 kB: read as an uploaded image is (its size checked on the header, so the
    bomb is never decompressed); the probe is unanswered and the others are asked and judged."""
    answer = bomb(13000) if answer == "bomb" else answer
    scene = (HERE / "spot.json").read_bytes()
    found = experiment(
        scene, render_png(json.loads(scene), ("no-shadows",)), fake_program(answer), Thresholds(2.0, 0.001)
    )
    lights = [a for a in found.answers if a.probe.kind is Kind.LIGHT]
    assert [a.verdict for a in lights] == ["unreadable", "unreadable"]
    assert found.answers[-1].probe.kind is Kind.CAMERA and found.answers[-1].verdict in ("right", "wrong")
    assert found.sentences[-1] == (
        "on the probe 'spot light 'key' alone' the program's image could not be read (not a PNG of its size)"
    )


@pytest.mark.parametrize("task", ["spot", "glass"])
def test_an_honest_program_answers_every_probe_right(tmp_path, task):
    found = asked(tmp_path, "", task)
    assert [a.verdict for a in found.answers] == ["right"] * len(found.answers)
    assert found.sentences == []


def counted(outcome: RunOutcome) -> tuple[Callable[[bytes], RunOutcome], list[bytes]]:
    """A program (no sandbox) that answers every probe with ``outcome``, and the scenes it was asked."""
    scenes: list[bytes] = []

    def run(scene: bytes) -> RunOutcome:
        scenes.append(scene)
        return outcome

    return run, scenes


def test_a_probe_that_times_out_ends_the_experiment():
    """A program that fails its task and then waits on each probe would cost the class (1 + probes) wall-time
    limits a task: the first probe that times out is the last asked."""
    scene = (HERE / "spot.json").read_bytes()
    run, scenes = counted(RunOutcome(Reason.TIMEOUT, "still running at the wall-time limit of 3 s", wall_seconds=3.0))
    found = experiment(scene, None, run, Thresholds(2.0, 0.001))
    assert len(scenes) == 1 and [a.verdict for a in found.answers] == ["timeout"]
    assert found.sentences[-1].endswith("the program's run timed out")


def test_a_students_probes_stop_once_its_allowance_of_time_is_spent():
    """Each probe answered just within its limit: the student's allowance (its tasks' together) ends them."""
    from service.programs.experiment import Allowance

    scene = (HERE / "spot.json").read_bytes()
    slow = RunOutcome(Reason.OK, "ok", render_png(json.loads(scene), ("no-shadows",)), wall_seconds=10.0)
    allowance = Allowance(25.0)
    run, scenes = counted(slow)
    experiment(scene, slow.image, run, Thresholds(2.0, 0.001), allowance=allowance)
    assert len(scenes) == 3 and allowance.seconds <= 0
    run, scenes = counted(slow)
    experiment(scene, slow.image, run, Thresholds(2.0, 0.001), allowance=allowance)  # (the next task's)
    assert scenes == []


def test_a_busy_machines_wait_is_not_charged_to_the_students_probes():
    """Probes that each took 10 s of wall time, 9 of them waiting for a CPU on a busy machine, cost the allowance
    their own second each: all of them are asked, as on an idle machine; a probe that waited for no CPU (asleep)
    costs its whole wall time."""
    from service.programs.experiment import Allowance, charged

    scene = (HERE / "spot.json").read_bytes()
    image = render_png(json.loads(scene), ("no-shadows",))
    busy = RunOutcome(Reason.OK, "ok", image, wall_seconds=10.0, cpu_seconds=0.5, waited_seconds=9.0)
    allowance = Allowance(25.0)
    run, scenes = counted(busy)
    experiment(scene, image, run, Thresholds(2.0, 0.001), allowance=allowance)
    assert len(scenes) > 3 and allowance.seconds == 25.0 - len(scenes)
    assert charged(RunOutcome(Reason.OK, "ok", wall_seconds=10.0, cpu_seconds=0.1)) == 10.0


def test_a_program_sleeping_on_its_probes_is_asked_one(tmp_path):
    """In the sandbox: the task rendered wrong at once, every probe slept on."""
    check_sandbox()
    folder = student(tmp_path, "no-shadows")
    (folder / "sleeper.py").write_text(
        "import json, runpy, sys, time\n"
        "if len(json.load(open(sys.argv[1]))['lights']) < 3:  # (a light alone: a probe)\n"
        "    time.sleep(3600)\n"
        "runpy.run_path('tracer.py', run_name='__main__')\n"
    )
    quick = Limits(wall_seconds=3.0, cpu_seconds=30, memory_bytes=1 << 30, output_bytes=1 << 20, folder_bytes=1 << 20)
    run = _runner(folder, Program("python3 sleeper.py {scene} {output}", limits=quick), "spot.json")
    scene = (HERE / "spot.json").read_bytes()
    first = run(scene)
    assert first.ok, first.detail
    found = experiment(scene, first.image, run, Thresholds(2.0, 0.001))
    assert [a.verdict for a in found.answers][-1] == "timeout"
    assert sum(a.verdict == "timeout" for a in found.answers) == 1
