"""phongray hidden from the sandbox (service.programs.hidden): an installation of it that a sandboxed Python
could import (an editable install for the system's Python, a copy without metadata) is covered, and one that
cannot be covered stops the batch as the TA's mistake.

The system's Python here has no phongray, and a test may not install one there for every other program on the
machine: each test shows the sandbox one more folder where the system's Python looks for packages
(``/usr/local/lib/python3.X/dist-packages``, bound from a folder of the test's), as if it were installed."""

import json
import shutil
import site
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from service.cli import main
from service.programs import Limits, ProgramRun, check_sandbox, run_program, sandbox
from service.programs import hidden as hidden_module
from service.programs.outcome import Reason
from service.programs.sandbox import SandboxUnavailable

ROOT = Path(__file__).parent.parent
SCENE = Path(__file__).parent / "programs" / "spot.json"
#: where the system's Python (Debian's) looks for packages installed for it by hand
SYSTEM_SITE = f"/usr/local/lib/python{sys.version_info[0]}.{sys.version_info[1]}/dist-packages"
#: a program that renders with phongray, in nine lines: a perfect image where phongray can be imported
NINE_LINES = """import sys

from schemas import load_scene
from tracer import encode_png, render

scene = load_scene(open(sys.argv[1], "rb").read())
with open(sys.argv[2], "wb") as out:
    out.write(encode_png(render(scene, threads=1)))
"""
#: a program that says whether phongray's tracer is there to import, without importing it (no NumPy needed):
#: exit 7 if it is, else a black 40×30 PNG
LOOKS = """import importlib.util, os, struct, sys, zlib

spec = importlib.util.find_spec("tracer")
places = list(spec.submodule_search_locations or []) if spec else []
if any(os.path.exists(os.path.join(p, "render.py")) for p in places):
    sys.exit(7)
def chunk(kind, body):
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
rows = zlib.compress(b"\\0" * (1 + 3 * 40) * 30)
head = struct.pack(">IIBBBBB", 40, 30, 8, 2, 0, 0, 0)
png = b"\\x89PNG\\r\\n\\x1a\\n" + chunk(b"IHDR", head) + chunk(b"IDAT", rows) + chunk(b"IEND", b"")
open(sys.argv[2], "wb").write(png)
"""


def shown(monkeypatch, *binds: tuple[str, str]) -> None:
    """The sandbox shows, besides the system's folders, each (folder of the machine, path in the sandbox)."""
    system = sandbox._system
    extra = [arg for there, here in binds for arg in ("--ro-bind", there, here)]
    monkeypatch.setattr(sandbox, "_system", lambda: [*system(), *extra])


def run(tmp_path: Path, program: str):
    check_sandbox()
    folder = tmp_path / "student"
    folder.mkdir(exist_ok=True)
    (folder / "render.py").write_text(program)
    return run_program(ProgramRun(folder, "python3 render.py {scene} {output}", SCENE, Limits(wall_seconds=60.0)))


def editable(monkeypatch) -> None:
    """phongray installed for the system's Python as this test session's is (an editable install: its .pth and
    finder among NumPy, pydantic and embreex), its source tree where the finder looks for it."""
    shown(monkeypatch, (site.getsitepackages()[0], SYSTEM_SITE), (str(ROOT), str(ROOT)))


def test_phongray_installed_for_the_systems_python_is_hidden(tmp_path, monkeypatch):
    editable(monkeypatch)
    looked = run(tmp_path, LOOKS)
    assert looked.reason is Reason.OK, looked.stderr_tail
    nine = run(tmp_path, NINE_LINES)
    assert nine.reason is Reason.CRASHED and "Error" in nine.stderr_tail  # (no schemas, no tracer to import)
    covers = hidden_module.HIDDEN.covers[(tuple(sandbox._system()), None)]
    assert f"{SYSTEM_SITE}/phongray-0.1.0.dist-info/" in covers
    assert any(c.endswith(".pth") and "phongray" in c for c in covers)


def test_a_copy_of_phongray_without_its_metadata_is_hidden(tmp_path, monkeypatch):
    """Its packages copied by hand where the system's Python looks: found by Python's own finder, and known
    by the names of their files."""
    copy = Path(tempfile.mkdtemp(prefix="phongray-copy-"))  # (in the session's folder: the sandbox's user reads it)
    try:
        copy.chmod(0o755)
        for package in ("tracer", "schemas", "service"):
            shutil.copytree(ROOT / package, copy / package, ignore=shutil.ignore_patterns("__pycache__"))
        shown(monkeypatch, (str(copy), SYSTEM_SITE))
        looked = run(tmp_path, LOOKS)
        assert looked.reason is Reason.OK, looked.stderr_tail
        assert set(hidden_module.HIDDEN.covers[(tuple(sandbox._system()), None)]) == {
            f"{SYSTEM_SITE}/{package}/" for package in ("tracer", "schemas", "service")
        }
    finally:
        shutil.rmtree(copy)


def test_phongray_that_cannot_be_hidden_stops_the_class_with_the_tas_error(tmp_path, monkeypatch, capsys):
    """Found again through its covers (here: the look always finds it): no student is run, exit 2, one line."""
    editable(monkeypatch)
    shown(monkeypatch, ("/usr/share/doc", "/opt/this-test"))  # (a set of folders no other test shows)
    monkeypatch.setattr(hidden_module, "_look", lambda runtime: [f"{SYSTEM_SITE}/tracer/"])
    with pytest.raises(SandboxUnavailable, match="phongray is installed where students' programs can import it"):
        check_sandbox()
    scenes, subs = tmp_path / "scenes", tmp_path / "subs"
    scenes.mkdir()
    (subs / "ann").mkdir(parents=True)
    shutil.copy(SCENE, scenes / "spot.json")
    (subs / "ann" / "render.py").write_text(NINE_LINES)
    code = main(
        [
            "grade-class",
            str(scenes),
            str(subs),
            "-o",
            str(tmp_path / "r"),
            "--run",
            "python3 render.py {scene} {output}",
        ]
    )
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and f"{SYSTEM_SITE}/tracer/" in err
    assert not (tmp_path / "r").exists()


def test_with_nothing_of_phongray_installed_nothing_is_covered():
    check_sandbox()
    assert hidden_module.HIDDEN.covers[(tuple(sandbox._system()), None)] == []
    assert hidden_module.argv(sandbox._system()) == []


def test_phongray_in_the_tas_runtime_is_hidden_from_a_class(tmp_path):
    """A TA's runtime (--runtime: a virtual environment of the system's python3) that holds phongray, as a TA
    might make one for NumPy: a class's programs cannot find it there."""
    folder = Path(tempfile.mkdtemp(prefix="runtime-"))  # (in the session's folder: the sandbox's user reads it)
    try:
        folder.chmod(0o755)
        env = folder / "env"
        subprocess.run(["/usr/bin/python3", "-m", "venv", "--without-pip", str(env)], check=True)
        (site_packages,) = env.glob("lib/python3*/site-packages")
        for package in ("tracer", "schemas", "service"):
            shutil.copytree(ROOT / package, site_packages / package, ignore=shutil.ignore_patterns("__pycache__"))
        subprocess.run(["chmod", "-R", "a+rX", str(folder)], check=True)
        scenes, subs = tmp_path / "scenes", tmp_path / "subs"
        scenes.mkdir()
        (subs / "ann").mkdir(parents=True)
        shutil.copy(SCENE, scenes / "spot.json")
        (subs / "ann" / "render.py").write_text(LOOKS)
        report = tmp_path / "report"
        code = main(["grade-class", str(scenes), str(subs), "-o", str(report), "-q", "--jobs", "1", "--runtime",
                     str(env), "--run", "python3 render.py {scene} {output}"])  # fmt: skip
        assert code == 0
        (row,) = json.loads((report / "report.json").read_text())
        assert row["run"] == "ok" and row["status"] == "fail", row  # (it found no phongray: its black image)
    finally:
        shutil.rmtree(folder)
