"""Diagnosis by experiment (service.programs.experiment): a buggy program asked its task's probes in the
sandbox, its answers put in sentences; an honest one answers every probe right.  The programs are
tests/programs/tracer.py with one mistake switched on."""

from pathlib import Path

import pytest

from service.programs import Limits, check_sandbox
from service.programs.experiment import Thresholds, experiment
from service.programs.job import Program, _runner

HERE = Path(__file__).parent / "programs"
LIMITS = Limits(wall_seconds=30.0, cpu_seconds=30, memory_bytes=1 << 30, output_bytes=1 << 20, folder_bytes=1 << 20)


def student(tmp_path: Path, mistake: str) -> Path:
    """A student's folder: the tracer and its mistakes.txt."""
    folder = tmp_path / (mistake or "honest")
    folder.mkdir()
    (folder / "tracer.py").write_text((HERE / "tracer.py").read_text())
    (folder / "mistakes.txt").write_text(mistake)
    return folder


def asked(tmp_path: Path, mistake: str, task: str):
    check_sandbox()
    run = _runner(
        student(tmp_path, mistake), Program("python3 tracer.py {scene} {output}", limits=LIMITS), f"{task}.json"
    )
    scene = (HERE / f"{task}.json").read_bytes()
    first = run(scene)
    assert first.ok, first.detail
    return experiment(scene, first.image, run, Thresholds(2.0, 0.001))


def test_a_spot_without_its_ramp_is_wrong_between_its_inner_and_outer_cone(tmp_path):
    found = asked(tmp_path, "spot-hard-edge", "spot")
    assert found.sentences[0] == "your spot light 'key' is wrong between its inner and outer cone"
    assert "alone, your point light 'fill' is right" in found.sentences


def test_glass_left_out_is_refraction_missing_with_reflection_right(tmp_path):
    found = asked(tmp_path, "no-refraction", "glass")
    assert found.sentences == ["reflection right, refraction missing"]


def test_no_shadows_makes_every_light_wrong_and_no_ramp_is_blamed(tmp_path):
    found = asked(tmp_path, "no-shadows", "spot")
    assert "your spot light 'key' is wrong" in found.sentences
    assert "your point light 'fill' is wrong" in found.sentences
    assert not any("cone" in s for s in found.sentences)


@pytest.mark.parametrize("task", ["spot", "glass"])
def test_an_honest_program_answers_every_probe_right(tmp_path, task):
    found = asked(tmp_path, "", task)
    assert [a.verdict for a in found.answers] == ["right"] * len(found.answers)
    assert found.sentences == []
