"""A student's program that prints its image (service/programs/runner.py, ``{stdout}``): its standard output is
its image, PPM as *Ray Tracing in One Weekend* prints it, graded as a written one, within the same limits.

The program is tests/programs/tracer.py, called from a few lines that print its render as a P3 instead of
writing a PNG; the sandbox's tests need bubblewrap (PHONGRAY_REQUIRE_SANDBOX=1 makes its absence a failure)."""

import json
import shutil
from pathlib import Path

import pytest

from service.cli import main
from service.programs import Limits, ProgramRun, Reason, run_program
from service.programs.program import Program

HERE = Path(__file__).parent / "programs"
#: prints tracer.py's render of the scene as a P3 on standard output, its progress on standard error
PRINTER = """\
import json, sys
import tracer
with open(sys.argv[1]) as given:
    scene = json.load(given)
scene.setdefault("objects", [])
scene.setdefault("lights", [])
scene["materials"] = {name: tracer.material(m) for name, m in scene.get("materials", {}).items()}
width, height, data = tracer.render(scene)  # (PNG rows: a filter byte, then the row's values)
print("rendering", width, "x", height, file=sys.stderr)
print("P3")
print(width, height)
print(255)
for top in range(0, len(data), 1 + 3 * width):
    row = data[top + 1 : top + 1 + 3 * width]
    for i in range(0, len(row), 3):
        print(row[i], row[i + 1], row[i + 2])
"""
QUICK = Limits(wall_seconds=60.0, cpu_seconds=60, memory_bytes=512 << 20, output_bytes=8 << 20)


@pytest.fixture
def student(tmp_path):
    folder = tmp_path / "subs" / "ann"
    folder.mkdir(parents=True)
    shutil.copy(HERE / "tracer.py", folder / "tracer.py")
    (folder / "printer.py").write_text(PRINTER)
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    shutil.copy(HERE / "spot.json", scenes / "spot.json")
    return tmp_path


def test_a_program_that_prints_its_image_is_graded_as_one_that_writes_it(student):
    code = main(
        [
            "grade-class",
            str(student / "scenes"),
            str(student / "subs"),
            "-o",
            str(student / "report"),
            "--run",
            "python3 printer.py {scene} {stdout}",
            "--run-timeout",
            "60",
            "-q",
        ]
    )
    assert code == 0
    (row,) = json.loads((student / "report" / "report.json").read_text())
    assert (row["status"], row["run"], row["task"]) == ("pass", "ok", "spot"), row["reason"]
    assert "rendering 40 x 30" in row["run_output"]  # standard error, apart from the image
    copy = (student / "report" / "submissions" / "ann" / "spot.png").read_bytes()
    assert copy.startswith(b"\x89PNG")  # the report shows a PPM as the PNG of its pixels


def test_what_a_program_prints_is_held_to_the_output_limit(student):
    (student / "subs" / "ann" / "flood.py").write_text("import sys\nwhile True:\n    sys.stdout.write('9' * 65536)\n")
    run = ProgramRun(
        student / "subs" / "ann",
        "python3 flood.py {stdout}",
        student / "scenes" / "spot.json",
        Limits(wall_seconds=20.0, output_bytes=1 << 20),
    )
    outcome = run_program(run)
    assert outcome.reason is Reason.OUTPUT_TOO_LARGE


def test_a_program_that_prints_nothing_has_no_output(student):
    run = ProgramRun(student / "subs" / "ann", "python3 -c pass {stdout}", student / "scenes" / "spot.json", QUICK)
    assert run_program(run).reason is Reason.NO_OUTPUT


@pytest.mark.parametrize(
    ("command", "error"),
    [
        ("python3 printer.py {scene} --out={stdout}", "stands alone"),
        ("python3 printer.py {scene} {output} {stdout}", "names both"),
        ("{stdout}", "the command is empty"),
        ("python3 printer.py {scene}", r"names no \{output\}.*or \{stdout\}"),
    ],
)
def test_a_template_that_misuses_stdout_is_the_tas_mistake(command, error):
    with pytest.raises(ValueError, match=error):
        Program(command)
