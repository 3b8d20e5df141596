"""The runtime the TA gives students' programs (service.programs.runtime): a folder shown read-only in the
sandbox with its bin/ first on the PATH, Debian packages checked before any student is run, and the
autograder's bundle carrying what its setup.sh installs.

The runtime here is a virtual environment of the system's Python (no pip, no network) holding one small
package of its own, ``course_runtime``, which a student's program imports as it would NumPy."""

import json
import os
import subprocess
import tempfile
import zipfile
from pathlib import Path

import pytest

from service.classgrade.bundled import REQUIREMENTS_FILE, load_program
from service.cli import main
from service.programs import check_sandbox
from service.programs.runtime import BUNDLED

HERE = Path(__file__).parent / "programs"
RUNNER = """\
import sys
import course_runtime
open(sys.argv[2], "wb").write(course_runtime.png())
"""
PACKAGE = """\
import struct, zlib
def png():
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    rows = b"".join(b"\\0" + b"\\0\\0\\0" * 160 for _ in range(120))
    return (b"\\x89PNG\\r\\n\\x1a\\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 160, 120, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))
"""


@pytest.fixture(scope="module")
def runtime() -> Path:
    """A virtual environment of /usr/bin/python3 (readable by a run's user) holding ``course_runtime``."""
    folder = Path(tempfile.mkdtemp(prefix="runtime-"))
    folder.chmod(0o755)
    env = folder / "env"
    subprocess.run(["/usr/bin/python3", "-m", "venv", "--without-pip", str(env)], check=True)
    (site,) = env.glob("lib/python3*/site-packages")
    (site / "course_runtime.py").write_text(PACKAGE)
    subprocess.run(["chmod", "-R", "a+rX", str(folder)], check=True)
    return env


def a_class(root: Path) -> tuple[Path, Path]:
    """One task, a black image, and one student whose program needs the runtime's package."""
    scenes, student = root / "scenes", root / "subs" / "ann"
    scenes.mkdir()
    student.mkdir(parents=True)
    scene = json.loads((HERE / "spot.json").read_text())
    scene["image"].update({"width": 160, "height": 120, "background": 0})
    scene["lights"], scene["objects"] = [], []
    scene.pop("ambient", None)
    (scenes / "black.json").write_text(json.dumps(scene))
    (student / "render.py").write_text(RUNNER)
    return scenes, root / "subs"


def grade(root: Path, *more: str) -> tuple[int, list[dict]]:
    scenes, subs = a_class(root)
    code = main(["grade-class", str(scenes), str(subs), "-o", str(root / "report"), "-q", "--jobs", "1",
                 "--run", "python3 render.py {scene} {output}", *more])  # fmt: skip
    rows = json.loads((root / "report" / "report.json").read_text()) if code == 0 else []
    return code, rows


def test_a_program_imports_what_the_runtime_holds(tmp_path, runtime):
    check_sandbox()
    code, rows = grade(tmp_path, "--runtime", str(runtime))
    assert code == 0 and rows[0]["status"] == "pass", rows
    without = tmp_path / "without"
    without.mkdir()
    code, rows = grade(without)
    assert code == 0 and rows[0]["run"] == "crashed" and "No module named 'course_runtime'" in rows[0]["run_output"]


def test_a_runtime_whose_python_the_sandbox_cannot_start_is_the_tas_one_line(tmp_path, runtime, capsys):
    broken = Path(tempfile.mkdtemp(prefix="runtime-"))
    broken.chmod(0o755)
    (broken / "bin").mkdir()
    (broken / "bin" / "python3").symlink_to(tmp_path / "a-python-not-shown")
    code, _ = grade(tmp_path, "--runtime", str(broken))
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1
    assert f"--runtime {broken}: its python3 does not start in the sandbox" in err and "/usr/bin/python3 -m venv" in err


@pytest.mark.parametrize(
    ("more", "words"),
    [
        (["--runtime-packages", "phongray-no-such-package"], "not installed here: phongray-no-such-package"),
        (["--runtime", "/nonexistent/runtime"], "--runtime /nonexistent/runtime: no such folder"),
        (["--runtime", "relative/env"], "name the folder by its absolute path"),
        (["--runtime-packages", "python3-numpy;rm"], "is not a Debian package's name"),
    ],
)
def test_a_runtime_that_is_not_there_stops_the_batch(tmp_path, capsys, more, words):
    code, _ = grade(tmp_path, *more)
    err = capsys.readouterr().err.strip()
    assert code == 2 and words in err and len(err.splitlines()) == 1


def test_installed_packages_pass_the_check(tmp_path):
    check_sandbox()
    code, rows = grade(tmp_path, "--runtime-packages", "bubblewrap")  # (installed wherever the sandbox runs)
    assert code == 0 and rows[0]["run"] == "crashed"  # (checked, then run: the package holds no course_runtime)


def test_the_bundle_carries_the_runtime_setup_sh_installs(tmp_path, capsys):
    scenes, _ = a_class(tmp_path)
    (tmp_path / "requirements.txt").write_text("numpy>=1.26\npillow\n")
    out = tmp_path / "autograder.zip"
    args = ["autograder", str(scenes), "-o", str(out), "--run", "python3 render.py {scene} {output}"]
    more = [
        "--runtime-packages",
        "python3-numpy,python3-pil",
        "--runtime-requirements",
        str(tmp_path / "requirements.txt"),
    ]
    assert main([*args, *more]) == 0
    with zipfile.ZipFile(out) as archive:
        archive.extractall(tmp_path / "bundle")
    course = tmp_path / "bundle" / "course"
    program = load_program(course)
    assert program is not None and program.runtime == BUNDLED and program.packages == ("python3-numpy", "python3-pil")
    assert (course / REQUIREMENTS_FILE).read_text() == "numpy>=1.26\npillow\n"
    setup = (tmp_path / "bundle" / "setup.sh").read_text()
    assert f"RUNTIME={BUNDLED}" in setup and "apt-get install -y -q $packages" in setup
    assert main([*args, "--runtime", "/opt/env", "-o", str(tmp_path / "b.zip")]) == 2
    assert "does not reach Gradescope" in capsys.readouterr().err
    assert os.path.exists(out)


def test_a_runtime_holding_the_course_is_refused_before_any_student(tmp_path, capsys):
    """--runtime naming the course folder (scenes, students, report, with the environment inside): every
    program would read the hidden scenes and the other students' code there."""
    (tmp_path / "env" / "bin").mkdir(parents=True)
    (tmp_path / "bin").mkdir()  # (a prefix: it is what it holds that refuses it)
    code, _ = grade(tmp_path, "--runtime", str(tmp_path))
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert f"--runtime {tmp_path}: it holds " in err and "which every program would see" in err


def test_a_runtime_holding_the_machines_temporary_folder_is_refused(tmp_path, capsys):
    """Every run's private copy of a student's folder is in the temporary folder while it runs."""
    code, _ = grade(tmp_path, "--runtime", tempfile.gettempdir())
    err = capsys.readouterr().err.strip()
    assert code == 2 and "it holds the machine's temporary folder" in err and len(err.splitlines()) == 1


def test_a_runtime_inside_the_students_folders_or_without_bin_is_refused(tmp_path, capsys):
    inside = tmp_path / "subs" / "bob" / "env"
    (inside / "bin").mkdir(parents=True)
    code, _ = grade(tmp_path, "--runtime", str(inside))
    err = capsys.readouterr().err.strip()
    assert code == 2 and "it is inside the students' folders" in err and len(err.splitlines()) == 1
    bare = Path(tempfile.mkdtemp(prefix="runtime-"))
    (tmp_path / "again").mkdir()
    code, _ = grade(tmp_path / "again", "--runtime", str(bare))
    err = capsys.readouterr().err.strip()
    assert code == 2 and "it has no bin/ folder" in err and len(err.splitlines()) == 1
