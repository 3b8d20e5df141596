"""A student's program graded as one job (service.classgrade.job): built once, run on each task, each image
graded as an upload's; a failed run or build is a failing grade with its reason, and the job goes on."""

import os
from pathlib import Path

import pytest

from schemas import load_scene
from service.classgrade.job import Program, ProgramJob, TaskScene, digest, grade_program
from service.classgrade.records import GradeJob
from service.programs import Limits, check_sandbox
from service.programs.pack import pack_folder
from tracer import encode_png, render

HERE = Path(__file__).parent / "programs"
LIMITS = Limits(wall_seconds=20.0, cpu_seconds=20, memory_bytes=1 << 30, output_bytes=1 << 20, folder_bytes=1 << 20)
RUN = "python3 tracer.py {scene} {output}"


@pytest.fixture(scope="module")
def tasks() -> tuple[TaskScene, ...]:
    check_sandbox()
    out = []
    for name in ("spot", "glass"):
        text = (HERE / f"{name}.json").read_bytes()
        reference = encode_png(render(load_scene(text), threads=1))
        out.append(TaskScene(name, GradeJob(text, reference, b"", 2.0, 0.001)))
    return tuple(out)


def folder(tmp_path: Path, mistakes: str = "", extra: str = "") -> Path:
    student = tmp_path / "student"
    student.mkdir()
    (student / "tracer.py").write_text(extra + (HERE / "tracer.py").read_text())
    (student / "mistakes.txt").write_text(mistakes)
    return student


def test_an_honest_program_passes_every_task_and_its_image_is_kept(tmp_path, tasks):
    graded = grade_program(ProgramJob(folder(tmp_path), Program(RUN, limits=LIMITS), tasks))
    assert {task: row.status for task, row in graded.items()} == {"spot": "pass", "glass": "pass"}
    assert graded["spot"].image.startswith(b"\x89PNG") and graded["spot"].run.run == "ok"
    assert graded["spot"].run.run_warning is None
    assert graded["spot"].experiment is None


def test_a_buggy_program_fails_with_its_mistake_found_by_experiment(tmp_path, tasks):
    graded = grade_program(ProgramJob(folder(tmp_path, "no-refraction"), Program(RUN, limits=LIMITS), tasks))
    assert graded["spot"].status == "pass"
    assert graded["glass"].status == "fail"
    assert graded["glass"].experiment == "reflection right, refraction missing"


def test_a_run_that_fails_is_a_failing_pair_with_its_reason(tmp_path, tasks):
    hang = 'import sys\nwhile "glass" in sys.argv[1]:\n    pass\n'
    quick = Limits(wall_seconds=3.0, cpu_seconds=20, memory_bytes=1 << 30, output_bytes=1 << 20, folder_bytes=1 << 20)
    graded = grade_program(ProgramJob(folder(tmp_path, extra=hang), Program(RUN, limits=quick), tasks))
    assert graded["spot"].status == "pass"  # the job went on
    glass = graded["glass"]
    assert glass.status == "fail" and glass.graded is None and glass.run.run == "timeout"
    assert glass.reason.startswith("the run failed: timeout: still running at the wall-time limit of 3 s")
    assert glass.experiment is None  # a run that failed is not asked more


def test_a_failed_build_fails_every_task_and_runs_none(tmp_path, tasks):
    student = folder(tmp_path)
    (student / "build.sh").write_text("echo 'tracer.c:3: error: expected ;' >&2\nexit 1\n")
    graded = grade_program(ProgramJob(student, Program(RUN, build="sh build.sh", limits=LIMITS), tasks))
    for row in graded.values():
        assert row.status == "fail" and row.reason.startswith("the build failed: crashed: crashed (exit 1)")
        assert "expected ;" in row.run.run_output


def test_a_build_runs_once_and_its_result_is_what_runs(tmp_path, tasks):
    student = folder(tmp_path, "no-refraction")
    (student / "build.sh").write_text(": > mistakes.txt\necho built >> builds.txt\n")
    graded = grade_program(ProgramJob(student, Program(RUN, build="sh build.sh", limits=LIMITS), tasks))
    assert {row.status for row in graded.values()} == {"pass"}
    assert not (student / "builds.txt").exists()  # built in its sandbox, never in the student's folder


@pytest.mark.parametrize(
    ("command", "words"),
    [
        ("python3 tracer.py {scene}", "names no {output}"),
        ("pyhton3 tracer.py {scene} {output}", "no program 'pyhton3'"),
        # a path that is no program, or one the sandbox does not show: every student's run would crash
        ("/usr/local/bin/no-such-node tracer.js {scene} {output}", "no program /usr/local/bin/no-such-node that"),
        ("/tmp/python3 tracer.py {scene} {output}", r"no program /tmp/python3 that .* \(the sandbox shows /usr,"),
    ],
)
def test_a_command_of_the_tas_that_cannot_run_is_refused_before_any_student(command, words):
    with pytest.raises(ValueError, match=words):
        Program(command)


def test_a_program_the_sandbox_does_not_show_is_refused_though_it_is_here(tmp_path):
    """An executable of the TA's machine outside the folders the sandbox shows (their home, /opt): every
    student's run would find nothing there."""
    program = tmp_path / "node"
    program.write_text("#!/bin/sh\n")
    program.chmod(0o755)
    with pytest.raises(ValueError, match=f"no program {program} that a student's program can run"):
        Program(f"{program} tracer.js {{scene}} {{output}}")
    assert Program(f"{program} tracer.js {{scene}} {{output}}", sandbox=False).run.startswith(str(program))


def test_the_digest_follows_the_files_and_the_commands_not_the_links(tmp_path):
    student = folder(tmp_path)
    program = Program(RUN, limits=LIMITS)
    first = digest(student, program)
    os.symlink("/etc/passwd", student / "passwd")
    assert digest(student, program) == first
    assert digest(student, Program(RUN, limits=Limits())) != first
    (student / "mistakes.txt").write_text("no-shadows")
    assert digest(student, program) != first


def test_an_output_that_is_not_a_png_is_invalid_as_an_upload_would_be(tmp_path, tasks):
    garbage = 'import sys\nopen(sys.argv[2], "wb").write(b"GIF89a not a png")\nsys.exit(0)\n'
    graded = grade_program(ProgramJob(folder(tmp_path, extra=garbage), Program(RUN, limits=LIMITS), tasks[:1]))
    assert graded["spot"].status == "invalid" and graded["spot"].experiment is None


def test_a_job_sent_with_its_pack_runs_the_packed_folder_wherever_it_is(tmp_path, tasks):
    """Where a job runs the student's folder may not exist (a Dask worker): what runs is the pack it carries;
    a pack of a folder over the limit fails every task, as the folder would."""
    student = folder(tmp_path, "no-refraction")
    program = Program(RUN, build="sh build.sh", limits=LIMITS)
    (student / "build.sh").write_text("echo built\n")
    pack = pack_folder(student, LIMITS.folder_bytes)
    elsewhere = tmp_path / "not-here" / "student"
    graded = grade_program(ProgramJob(elsewhere, program, tasks, pack))
    assert graded["spot"].status == "pass"
    assert graded["glass"].experiment == "reflection right, refraction missing"
    too_large = pack_folder(student, 100)
    for row in grade_program(ProgramJob(elsewhere, program, tasks, too_large)).values():
        assert row.reason == "the build failed: folder-too-large: the student's folder is larger than the limit"


#: runs the honest tracer, then puts a private chunk of 900 kB (no decoder shows it) into the PNG it wrote
BLOATER = """\
import runpy, struct, sys, zlib
runpy.run_path("tracer.py", run_name="__main__")
data = open(sys.argv[2], "rb").read()
blob = b"\\0" * 900_000
chunk = struct.pack(">I", len(blob)) + b"prVt" + blob + struct.pack(">I", zlib.crc32(b"prVt" + blob))
open(sys.argv[2], "wb").write(data[:33] + chunk + data[33:])  # (after the signature and IHDR)
"""


def test_what_is_kept_of_a_programs_image_is_the_png_of_its_pixels(tmp_path, tasks):
    """A PNG may carry megabytes of a chunk no decoder shows; the report keeps the PNG of the pixels graded."""
    from tracer import decode_png

    student = folder(tmp_path)
    (student / "bloat.py").write_text(BLOATER)
    graded = grade_program(ProgramJob(student, Program("python3 bloat.py {scene} {output}", limits=LIMITS), tasks[:1]))
    kept = graded["spot"].image
    assert graded["spot"].status == "pass" and b"prVt" not in kept and len(kept) < 100_000
    assert (decode_png(kept) == decode_png(tasks[0].grading.reference)).all()
