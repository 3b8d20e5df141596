"""phongray autograder: the Gradescope bundle, built here and run against an /autograder-like folder."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from service.classgrade.uploads import task_files
from service.cli import main

from helpers import run_autograder

CLASS = Path(__file__).resolve().parent.parent / "examples" / "class"


@pytest.fixture(scope="module")
def bundle(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("bundle") / "autograder.zip"
    assert main(["autograder", str(CLASS / "scenes"), "-o", str(out), "--tasks", str(CLASS / "tasks.json")]) == 0
    return out


def test_the_bundle_has_gradescopes_two_scripts_at_its_root_and_phongray_beside_them(bundle: Path):
    with zipfile.ZipFile(bundle) as archive:
        info = {i.filename: i for i in archive.infolist()}
    for script in ("setup.sh", "run_autograder"):
        assert info[script].external_attr >> 16 & 0o111, script  # executable
    assert "phongray/pyproject.toml" in info and "phongray/service/classgrade/autograder.py" in info
    assert {n for n in info if n.startswith("course/scenes/")} == {
        f"course/scenes/{t}.json" for t in ("lights", "mirror", "spheres")
    }
    assert len([n for n in info if n.startswith("course/references/")]) == 3


def test_a_submission_is_graded_a_test_per_task_with_its_names_forgiven(bundle: Path, tmp_path: Path):
    done, results = run_autograder(
        bundle,
        tmp_path,
        {
            "Mirror (1).png": CLASS / "submissions" / "ada" / "mirror.png",
            "spheres-1.png": CLASS / "submissions" / "gus" / "spheres.png",
            "notes.txt": CLASS / "submissions" / "eli" / "notes.txt",
        },
    )
    assert done.returncode == 0, done.stderr
    tests = {t["name"]: t for t in results["tests"]}
    assert set(tests) == {"lights", "mirror", "spheres"}
    assert (tests["mirror"]["score"], tests["mirror"]["max_score"], tests["mirror"]["status"]) == (5.0, 5.0, "passed")
    # (the sample class's tasks.json takes 1 of the spheres' 2 points for no shadow rays: partial credit)
    assert (tests["spheres"]["score"], tests["spheres"]["max_score"]) == (1.0, 2.0)
    assert "Likely: no shadow rays" in tests["spheres"]["output"]
    assert tests["lights"]["score"] == 0.0 and tests["lights"]["output"].startswith("missing")
    assert results["score"] == 6.0
    assert "graded as mirror: Mirror (1).png" in done.stdout
    assert "not graded: notes.txt: names no task" in done.stdout


def test_uploads_as_students_make_them_images_one_folder_down_near_misses_and_their_own_names(
    bundle: Path, tmp_path: Path
):
    import io
    import tempfile

    import numpy as np
    from PIL import Image

    pixels = np.asarray(Image.open(CLASS / "submissions" / "ada" / "lights.png").convert("RGB"))
    h, w, _ = pixels.shape
    (tmp_path / "lights.ppm").write_bytes(f"P6\n{w} {h}\n255\n".encode() + pixels.tobytes())
    buf = io.BytesIO()
    Image.open(CLASS / "submissions" / "ada" / "spheres.png").convert("RGB").save(buf, format="JPEG")
    (tmp_path / "spheres.jpg").write_bytes(buf.getvalue())
    done, results = run_autograder(
        bundle,
        tmp_path / "root",
        {
            "hw3/Lights.ppm": tmp_path / "lights.ppm",  # one folder down (a zip's folder), a PPM
            "hw3/Mirrors.png": CLASS / "submissions" / "ada" / "mirror.png",  # named nearly as the task
            "Spheres (2).jpg": tmp_path / "spheres.jpg",
        },
    )
    assert done.returncode == 0, done.stderr
    tests = {t["name"]: t for t in results["tests"]}
    assert (tests["lights"]["status"], tests["lights"]["score"]) == ("passed", 3.0), tests["lights"]["output"]
    assert tests["mirror"]["output"] == "missing: no mirror.png (found hw3/Mirrors.png: did you mean mirror.png?)"
    assert tests["spheres"]["output"] == "invalid: Spheres (2).jpg: image is a JPEG; PNG or PPM required"
    assert tempfile.gettempdir() not in json.dumps(results)  # no temporary path, anywhere a student reads
    assert "submissions/" not in json.dumps(results) + done.stdout  # (the class of one it was graded as)
    assert "not graded: hw3/Mirrors.png: names no task (did you mean mirror?)" in done.stdout


def test_an_honest_tracers_ray_offset_passes_in_the_autograder_and_says_so(tmp_path: Path):
    import student

    from schemas import load_scene
    from tracer import encode_png

    whitted = CLASS.parent / "04_whitted.json"  # (where a 1e-3 normal offset fails the reference alone)
    (tmp_path / "scenes").mkdir()
    shutil.copyfile(whitted, tmp_path / "scenes" / "whitted.json")
    out = tmp_path / "autograder.zip"
    assert main(["autograder", str(tmp_path / "scenes"), "-o", str(out)]) == 0
    honest = tmp_path / "whitted.png"
    honest.write_bytes(
        encode_png(student.render(load_scene(whitted.read_bytes()), style=student.STYLES["offset 1e-3"]))
    )
    done, results = run_autograder(out, tmp_path / "root", {"Whitted.png": honest})
    (test,) = results["tests"]
    assert (test["score"], test["status"]) == (1.0, "passed"), test["output"]
    assert test["output"].startswith("passed, as rendered with a ray offset of 0.001 along the normal: ")


def test_a_broken_bundle_writes_results_that_say_so_and_exits_2(tmp_path: Path, bundle: Path):
    done, results = run_autograder(bundle, tmp_path, {})
    assert done.returncode == 0
    shutil.rmtree(tmp_path / "source" / "course" / "scenes")
    env = {**os.environ, "PHONGRAY_AUTOGRADER_ROOT": str(tmp_path), "PHONGRAY_AUTOGRADER_PYTHON": sys.executable}
    again = subprocess.run(
        ["bash", str(tmp_path / "source" / "run_autograder")], env=env, text=True, capture_output=True, timeout=600
    )
    assert again.returncode == 2 and len(again.stderr.strip().splitlines()) == 1
    assert json.loads((tmp_path / "results" / "results.json").read_text())["output"].startswith(
        "The autograder could not grade this submission"
    )


def test_a_tas_invalid_scene_stops_the_build_in_one_line_with_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture):
    scenes = tmp_path / "scenes"
    scenes.mkdir()
    (scenes / "broken.json").write_text('{"camera": 1}')
    out = tmp_path / "autograder.zip"
    assert main(["autograder", str(scenes), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "broken.json" in err[0]
    assert not out.exists()


@pytest.mark.parametrize(
    ("names", "expected"),
    [
        (["Spheres.PNG"], {"spheres": "Spheres.PNG"}),
        (["Spheres (1).png"], {"spheres": "Spheres (1).png"}),
        (["spheres.png", "spheres-1.png", "spheres-2.png"], {"spheres": "spheres-2.png"}),  # the latest copy
        (["mirror.jpg", "mirror.png"], {"mirror": "mirror.png"}),
        (["mirror.jpg"], {"mirror": "mirror.jpg"}),  # graded, and so reported as the JPEG it is
        (["lights2.png", "readme.txt"], {}),
    ],
)
def test_which_file_is_a_tasks(names: list[str], expected: dict[str, str]):
    chosen, left = task_files(names, ["spheres", "mirror", "lights"])
    assert {task: found.name for task, found in chosen.items()} == expected
    assert len(left) == len(names) - len(expected)


def test_the_bundles_accepted_variants_are_rendered_beforehand(tmp_path: Path):
    """A submission that fails the reference is graded against the bundle's own renders of the variants, not
    renders made in Gradescope's container: with the bundle's renders replaced by a wrong image (no shadow
    rays), that image passes "as rendered with a ray offset of 0.001 along the normal", which no real render of it
    would give."""
    from schemas import load_scene
    from service.diagnosis.accepting import accepted_ladders, file_name
    from tracer import Renderer, encode_png
    from tracer.scene.variants import VARIANTS

    whitted = CLASS.parent / "04_whitted.json"
    (tmp_path / "scenes").mkdir()
    shutil.copyfile(whitted, tmp_path / "scenes" / "whitted.json")
    out = tmp_path / "autograder.zip"
    assert main(["autograder", str(tmp_path / "scenes"), "-o", str(out)]) == 0
    with zipfile.ZipFile(out) as archive:
        stored = sorted(n.rsplit("/", 1)[1] for n in archive.namelist() if n.startswith("course/variants/"))
    ladders = accepted_ladders(load_scene(whitted.read_bytes()), None)
    assert stored == sorted(file_name(rung.options) for rungs in ladders for rung in rungs)
    assert [len(rungs) for rungs in ladders] == [7, 4]  # (0.001 … 0.02 and 0.03 along the normal; t_min 0.003 …)
    wrong = tmp_path / "wrong.png"
    wrong.write_bytes(encode_png(Renderer(load_scene(whitted.read_bytes()), VARIANTS["no-shadows"][0]).pixels()))
    done, results = run_autograder(out, tmp_path / "honest", {"whitted.png": wrong})
    assert results["tests"][0]["status"] == "failed"  # (against the bundle's true renders)
    root = tmp_path / "faked"
    for folder in ("source", "submission", "results"):
        (root / folder).mkdir(parents=True)
    with zipfile.ZipFile(out) as archive:
        archive.extractall(root / "source")
    for png in (root / "source" / "course" / "variants").rglob("*.png"):
        shutil.copyfile(wrong, png)
    shutil.copyfile(wrong, root / "submission" / "whitted.png")
    env = {**os.environ, "PHONGRAY_AUTOGRADER_ROOT": str(root), "PHONGRAY_AUTOGRADER_PYTHON": sys.executable}
    subprocess.run(["bash", str(root / "source" / "run_autograder")], env=env, capture_output=True, timeout=600)
    (test,) = json.loads((root / "results" / "results.json").read_text())["tests"]
    assert test["output"].startswith("passed, as rendered with a ray offset of 0.001 along the normal: ")
