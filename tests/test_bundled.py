"""The autograder of a program assignment (service.classgrade.bundled): ``phongray autograder --run`` bundles
the program's commands with the hidden scenes; run_autograder runs the uploaded program in the sandbox on
each task scene and writes the student's results, showing what tasks.json's ``show`` allows."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import pytest

from service.classgrade.bundled import load_program, program_json
from service.cli import main
from service.course.errors import ClassError
from service.programs import Limits, check_sandbox
from service.programs.program import Program

from helpers import run_autograder

HERE = Path(__file__).parent / "programs"
RUN = "python3 tracer.py {scene} {output}"


@pytest.fixture(scope="module")
def bundle(tmp_path_factory: pytest.TempPathFactory) -> Path:
    course = tmp_path_factory.mktemp("course")
    (course / "scenes").mkdir()
    for task in ("spot", "glass"):
        shutil.copyfile(HERE / f"{task}.json", course / "scenes" / f"{task}.json")
    (course / "tasks.json").write_text(json.dumps({"spot": {"show": "verdict"}, "glass": {"show": "diagnosis"}}))
    out = course / "autograder.zip"
    assert (
        main(
            [
                "autograder",
                str(course / "scenes"),
                "-o",
                str(out),
                "--tasks",
                str(course / "tasks.json"),
                "--run",
                RUN,
                "--run-timeout",
                "20",
                "--memory",
                "1G",
            ]
        )
        == 0
    )
    return out


def graded(bundle: Path, tmp_path: Path, mistakes: str) -> tuple[subprocess.CompletedProcess[str], dict]:
    """The student's program, with its ``mistakes``, uploaded and graded by the bundle as Gradescope runs it."""
    (tmp_path / "mistakes.txt").write_text(mistakes)
    files = {"tracer.py": HERE / "tracer.py", "mistakes.txt": tmp_path / "mistakes.txt"}
    return run_autograder(bundle, tmp_path / "autograder", files)


def test_the_bundle_keeps_the_programs_commands_and_limits(bundle: Path, tmp_path: Path):
    with zipfile.ZipFile(bundle) as archive:
        archive.extractall(tmp_path)
    program = load_program(tmp_path / "course")
    assert program == Program(RUN, limits=Limits(wall_seconds=20.0, cpu_seconds=20, memory_bytes=1 << 30))


def test_an_uploaded_program_is_run_on_the_hidden_scenes_and_graded(bundle: Path, tmp_path: Path):
    check_sandbox()
    done, results = graded(bundle, tmp_path, "no-refraction")
    assert done.returncode == 0, done.stderr
    tests = {t["name"]: t for t in results["tests"]}
    assert tests["spot"]["status"] == "passed" and tests["glass"]["status"] == "failed"
    assert "reflection right, refraction missing" in tests["glass"]["output"]  # show: diagnosis
    assert results["score"] == 1


def test_verdict_shows_no_diagnosis(bundle: Path, tmp_path: Path):
    check_sandbox()
    done, results = graded(bundle, tmp_path, "spot-hard-edge")
    spot = {t["name"]: t for t in results["tests"]}["spot"]
    assert spot["status"] == "failed" and spot["output"].startswith("fail: ")
    assert "Likely" not in spot["output"] and "cone" not in spot["output"]  # show: verdict


def test_a_program_file_that_is_not_one_is_the_tas_mistake(tmp_path: Path):
    (tmp_path / "program.json").write_bytes(program_json(Program(RUN)).replace(b'"run"', b'"rnu"'))
    with pytest.raises(ClassError, match="not a program file"):
        load_program(tmp_path)


SNOOP = """import os, shutil, sys
scene, output = sys.argv[1], sys.argv[2]
for folder, _, files in os.walk({root!r}):  # the bundle's reference (its only task's), if it could be read
    for name in files:
        if os.path.basename(folder) == "references" and name.endswith(".png"):
            shutil.copyfile(os.path.join(folder, name), output)
            sys.exit(0)
sys.exit("nothing of the autograder could be read")
"""


def test_without_the_sandbox_a_program_cannot_read_the_bundle(tmp_path: Path):
    # a bundle made with --no-sandbox (a container that cannot start bubblewrap): each run is still a user of its
    # own, and /autograder is closed to it, so the hidden references cannot be handed in as the program's output
    course = tmp_path / "course"
    (course / "scenes").mkdir(parents=True)
    shutil.copyfile(HERE / "spot.json", course / "scenes" / "spot.json")
    out = course / "autograder.zip"
    assert main(["autograder", str(course / "scenes"), "-o", str(out), "--run", RUN, "--no-sandbox"]) == 0
    open_place = Path(tempfile.mkdtemp(prefix="phongray-gs-"))  # (pytest's own folders are closed to others)
    try:
        os.chmod(open_place, 0o755)
        root = open_place / "autograder"
        for folder in ("source", "submission", "results"):
            (root / folder).mkdir(parents=True)
            os.chmod(root / folder, 0o755)
        os.chmod(root, 0o755)
        with zipfile.ZipFile(out) as archive:
            archive.extractall(root / "source")
        assert len(list((root / "source" / "course" / "references").glob("*.png"))) == 1  # (there to be stolen)
        (root / "submission" / "tracer.py").write_text(SNOOP.format(root=str(root)))
        env = {**os.environ, "PHONGRAY_AUTOGRADER_ROOT": str(root), "PHONGRAY_AUTOGRADER_PYTHON": sys.executable}
        done = subprocess.run(
            ["bash", str(root / "source" / "run_autograder")],
            cwd=root,
            env=env,
            text=True,
            capture_output=True,
            timeout=600,
        )
        results = json.loads((root / "results" / "results.json").read_text())
    finally:
        shutil.rmtree(open_place)
    assert done.returncode == 0, done.stderr
    assert results["score"] == 0 and results["tests"][0]["status"] == "failed", results
