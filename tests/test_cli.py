"""The phongray command: renders, validates, and never prints a traceback."""

import json
import subprocess
import sys

import pytest

from helpers import SCENES, reference
from service.cli import main
from tracer import decode_png


def run(*args, stdin=None):
    return subprocess.run([sys.executable, "-m", "service.cli", *args], capture_output=True, input=stdin,
                          timeout=120)


def test_render_writes_the_reference_image(tmp_path):
    out = tmp_path / "out.png"
    assert main(["render", str(SCENES / "01_three_spheres.json"), "-o", str(out), "-q"]) == 0
    assert (decode_png(out.read_bytes()) == reference("01_three_spheres")).mean() > 0.999


def test_render_overrides_size_and_samples(tmp_path):
    out = tmp_path / "out.png"
    assert main(["render", str(SCENES / "01_three_spheres.json"), "-o", str(out), "--width", "20",
                 "--height", "10", "--samples", "2", "-q"]) == 0
    assert decode_png(out.read_bytes()).shape == (10, 20, 3)


def test_validate_ok_and_errors(tmp_path, capsys):
    assert main(["validate", str(SCENES / "05_mesh.json")]) == 0
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"camera": {"position": [0, 0, 1], "look_at": [0, 0, 0]},
                               "image": {"width": 1, "height": 1},
                               "objects": [{"type": "sphere", "material": "x", "center": [0, 0, 0], "radius": -1}]}))
    assert main(["validate", str(bad)]) == 1
    assert "objects[0].radius: must be > 0" in capsys.readouterr().out


def test_validate_prints_names_that_are_not_valid_unicode(tmp_path):
    data = json.loads((SCENES / "01_three_spheres.json").read_text())
    data["objects"][0]["material"] = "\ud800"
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(data))  # ASCII: the lone surrogate as the escape \ud800
    result = run("validate", str(bad))
    assert result.returncode == 1 and b"Traceback" not in result.stderr
    assert b"unknown material '\\ud800'" in result.stdout


def test_schema_prints_json(capsys):
    assert main(["schema"]) == 0
    assert json.loads(capsys.readouterr().out)["type"] == "object"


@pytest.mark.parametrize("content", [b"", b"{", b"\x89PNG\r\n", b"[]", b'{"camera": 1}', b"[" * 50000])
def test_bad_input_gives_one_line_and_no_traceback(tmp_path, content):
    path = tmp_path / "scene.json"
    path.write_bytes(content)
    for command in (["validate", str(path)], ["render", str(path), "-o", str(tmp_path / "x.png")]):
        result = run(*command)
        assert result.returncode != 0
        assert b"Traceback" not in result.stderr + result.stdout


def test_missing_file_and_unwritable_output(tmp_path):
    result = run("render", str(tmp_path / "missing.json"), "-o", str(tmp_path / "x.png"))
    assert result.returncode == 2 and b"cannot read" in result.stderr and b"Traceback" not in result.stderr
    result = run("render", str(SCENES / "07_spotlights.json"), "-o", str(tmp_path / "no" / "dir" / "x.png"))
    assert result.returncode == 2 and b"cannot write" in result.stderr


def test_render_from_stdin_to_stdout():
    result = run("render", "-", "-o", "-", "-q", stdin=(SCENES / "07_spotlights.json").read_bytes())
    assert result.returncode == 0 and result.stdout.startswith(b"\x89PNG")


def test_progress_bar_draws_only_when_enabled_and_late(capsys):
    from service.cli import ProgressBar

    quiet = ProgressBar(delay=0.0)
    quiet.enabled = False
    quiet(5, 10)
    bar = ProgressBar(delay=0.0)
    bar.enabled = True  # as on a terminal
    bar(5, 10)
    bar.close()
    late = ProgressBar(delay=3600.0)
    late.enabled = True
    late(5, 10)
    err = capsys.readouterr().err
    assert err.count("50.0%") == 1 and err.endswith("\n")


def test_absurd_image_size_is_refused_not_attempted(tmp_path):
    data = json.loads((SCENES / "01_three_spheres.json").read_text())
    data["image"]["width"] = 10**12
    path = tmp_path / "huge.json"
    path.write_text(json.dumps(data))
    result = run("render", str(path), "-o", str(tmp_path / "x.png"))
    assert result.returncode == 2 and b"more than phongray renders" in result.stderr


def test_absurd_area_light_grid_is_refused_not_attempted(tmp_path):
    data = json.loads((SCENES / "03_soft_shadows.json").read_text())
    data["lights"][1]["samples"] = [10**9, 10**9]
    path = tmp_path / "huge.json"
    path.write_text(json.dumps(data))
    result = run("render", str(path), "-o", str(tmp_path / "x.png"))
    assert result.returncode == 2 and b"light samples are more than phongray renders" in result.stderr
