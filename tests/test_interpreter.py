"""An interpreter that cannot start within a run's limits is the TA's mistake (service.programs.interpreter):
found before any student is run, in one line, with the memory it starts with."""

from pathlib import Path

from service.cli import main
from service.programs import Limits, check_sandbox
from service.programs.interpreter import fails_to_start
from service.programs.program import Program

HERE = Path(__file__).resolve().parent
SPHERES = HERE.parent / "examples" / "01_three_spheres.json"


def _class(root: Path) -> tuple[Path, Path]:
    """One task scene and one student whose program writes an empty file."""
    scenes, subs = root / "scenes", root / "subs" / "ann"
    scenes.mkdir()
    subs.mkdir(parents=True)
    (scenes / "spheres.json").write_text(SPHERES.read_text())
    (subs / "render.py").write_text("import sys\nopen(sys.argv[2], 'wb').close()\n")
    return scenes, subs.parent


def test_python_starting_within_the_default_limits_is_no_mistake():
    check_sandbox()
    assert fails_to_start(Program("python3 render.py {scene} {output}")) is None


def test_a_students_own_program_is_not_looked_at():
    # (./tracer is the student's: what it needs is theirs; 1 MiB would stop any interpreter)
    assert fails_to_start(Program("./tracer {scene} {output}", limits=Limits(memory_bytes=1 << 20))) is None


def test_python_that_cannot_start_within_the_memory_stops_the_class_before_any_student(tmp_path, capsys):
    """Python under 4 MiB does not start (a crash or out of memory, whichever way the memory is held): before,
    every student's run was recorded as crashed."""
    check_sandbox()
    scenes, subs = _class(tmp_path)
    report = tmp_path / "report"
    run = ["--run", "python3 render.py {scene} {output}", "--memory", "4M"]
    assert main(["grade-class", str(scenes), str(subs), "-o", str(report), *run, "-q"]) == 2
    said = capsys.readouterr().err.strip().splitlines()
    assert len(said) == 1 and said[0].startswith("phongray: --memory 4M: python3 fails as it starts"), said
    assert "it starts with --memory " in said[0]  # (the least of 8M, 16M, …, in which it does)
    assert not (report / "report.json").exists()  # (no student graded)


def test_an_autograder_whose_interpreter_cannot_start_is_not_written(tmp_path, capsys):
    """On Gradescope every student would get the same "could not grade": the bundle is refused as it is made."""
    check_sandbox()
    scenes, _ = _class(tmp_path)
    bundle = tmp_path / "autograder.zip"
    run = ["--run", "python3 render.py {scene} {output}", "--memory", "4M"]
    assert main(["autograder", str(scenes), "-o", str(bundle), *run]) == 2
    said = capsys.readouterr().err.strip().splitlines()
    assert len(said) == 1 and "python3 fails as it starts" in said[0], said
    assert not bundle.exists()
