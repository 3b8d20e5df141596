"""phongray in a student's program (service.classgrade.copied): its own code in the folder is counted by the
lines it shares with phongray's source, far more than any program written apart from it shares."""

import shutil
import site
from pathlib import Path

from service.classgrade.copied import LINES, fingerprint, phongray_code

ROOT = Path(__file__).parent.parent
HERE = Path(__file__).parent / "programs"


def test_a_folder_holding_phongray_is_told_from_programs_written_apart_from_it(tmp_path):
    vendored = tmp_path / "vendored"
    for package in ("tracer", "schemas"):  # (what rendering needs; renamed, as a student might)
        shutil.copytree(ROOT / package, vendored / f"my_{package}", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(HERE / "tracer.py", vendored / "render.py")
    count, where = phongray_code(vendored, 100 * 1000 * 1000, 10_000)
    assert count > 20 * LINES and where.startswith("my_tracer/")
    honest = tmp_path / "honest"
    honest.mkdir()
    shutil.copy(HERE / "tracer.py", honest / "tracer.py")
    assert phongray_code(honest, 100 * 1000 * 1000, 10_000)[0] < 10
    numpy = Path(site.getsitepackages()[0]) / "numpy"  # (a student's vendored NumPy is not phongray)
    assert phongray_code(numpy, 100 * 1000 * 1000, 10_000)[0] < 10


def test_the_count_stops_at_the_folders_limits(tmp_path):
    """Past the bytes or the entries a run's copy would hold, nothing more is read (such a folder is not run)."""
    shutil.copytree(ROOT / "tracer", tmp_path / "tracer", ignore=shutil.ignore_patterns("__pycache__"))
    (tmp_path / "a.txt").write_text("x" * 100)  # (read first: the files of the folder itself, by name)
    assert phongray_code(tmp_path, 100 * 1000 * 1000, 10_000)[0] > LINES
    assert phongray_code(tmp_path, 50, 10_000) == (0, "")  # (a.txt took the budget)
    assert phongray_code(tmp_path, 100 * 1000 * 1000, 1) == (0, "")  # (two entries at the top: over)
    assert len(fingerprint()) > 5000
