"""A student's tracer in C (tests/programs/ctracer), written from the scene format alone, graded by phongray.

The calibration of the grading rule from outside Python: the honest float64 tracer passes every example; its
honest styles (float32 throughout, shadow and secondary rays started 1e-4 or 1e-3 of the scene's size off the
surface along the normal, or by a t_min of 1e-3) pass too, against the reference or an accepted variant; and
each classic mistake, made as a student makes it in C, fails on a scene that shows it.  ctracer is compiled
with gcc into the test's own folder; its PNG writer, JSON reader and every equation are its own.
"""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent / "programs" / "ctracer"))

import matrix  # noqa: E402

from tracer import decode_png  # noqa: E402

SCENES = Path(__file__).parent / "programs" / "ctracer" / "scenes"
EXAMPLES = {path.stem: path for path in matrix.EXAMPLES}
#: the honest styles held to a pass on every example (matrix.py also prints t_min 1e-4)
STYLES = ("float32", "offset 1e-4", "offset 1e-3", "t_min 1e-3")
#: each mistake, on a scene that shows it: an example, or one of ctracer's own scenes where no example does
SHOWN_BY = {
    "no-shadows": "01_three_spheres",
    "shadow-acne": "01_three_spheres",
    "blinn-phong": "01_three_spheres",
    "specular-behind": "light_below",
    "gamma": "01_three_spheres",
    "no-attenuation": "02_all_lights",
    "no-ambient": "01_three_spheres",
    "no-specular": "01_three_spheres",
    "normals-not-flipped": "floor_facing_down",
    "image-flipped": "01_three_spheres",
    "no-half-pixel": "01_three_spheres",
    "horizontal-fov": "01_three_spheres",
    "aspect-inverted": "01_three_spheres",
    "camera-up-as-given": "01_three_spheres",
    "area-not-divided": "03_soft_shadows",
    "area-samples-at-corners": "03_soft_shadows",
    "spot-radians": "07_spotlights",
    "depth-plus-one": "mirrors",
    "depth-minus-one": "mirrors",
    "ior-inverted": "04_whitted",
    "offset-too-large": "02_all_lights",
    "reflect-sign": "01_three_spheres",
    "checker-ignored": "06_orthographic",
    "checker-truncated": "06_orthographic",
    "colours-not-clamped": "overexposed",
    "ambient-from-diffuse": "01_three_spheres",
    "spot-ramp-angle": "07_spotlights",
    "transparent-no-shadows": "04_whitted",
    "no-reflection": "04_whitted",
    "bounce-miss-black": "04_whitted",
    "no-refraction": "04_whitted",
    "left-handed": "01_three_spheres",
    "samples-ignored": "08_antialiased",
    "bgr": "01_three_spheres",
    "normals-not-normalised": "05_mesh",
}
#: at most this size is rendered (a copy of a larger scene, such as the Cornell-box homework, is made smaller)
WIDTH, HEIGHT = 160, 120


@pytest.fixture(scope="module")
def ctracer(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if shutil.which("gcc") is None:
        pytest.skip("gcc is not installed: the C student tracer cannot be built")
    return matrix.build(tmp_path_factory.mktemp("ctracer"))


@pytest.fixture(scope="module")
def scenes(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Every scene by name, copied at most WIDTH × HEIGHT (the samples and everything else kept)."""
    folder, found = tmp_path_factory.mktemp("scenes"), {}
    for path in [*matrix.EXAMPLES, *sorted(SCENES.glob("*.json"))]:
        scene = json.loads(path.read_text())
        if scene["image"]["width"] * scene["image"]["height"] > WIDTH * HEIGHT:
            scene["image"].update(width=WIDTH, height=HEIGHT)
            path = folder / path.name
            path.write_text(json.dumps(scene))
        found[path.stem] = path
    return found


@pytest.fixture(scope="module")
def grader() -> matrix.Grader:
    return matrix.Grader()


def graded(ctracer: Path, grader: matrix.Grader, scene: Path, row: str, out: Path) -> dict:
    """ctracer's image of ``scene`` in style or with mistake ``row``, graded (without the diagnosis)."""
    image = matrix.render(ctracer, scene, out, matrix.switches(row, json.loads(scene.read_text())))
    return grader.grade(scene, image, diagnose=False)


@pytest.mark.parametrize("example", list(EXAMPLES))
def test_honest_float64_passes_against_the_reference(
    ctracer: Path, grader: matrix.Grader, scenes: dict[str, Path], example: str, tmp_path: Path
) -> None:
    result = graded(ctracer, grader, scenes[example], "float64", tmp_path / "out.png")
    assert result["passed"], result["reason"]
    assert result["accepted"] is None  # (the reference itself, no accepted variant needed)


@pytest.mark.parametrize("style", STYLES)
@pytest.mark.parametrize("example", list(EXAMPLES))
def test_honest_styles_pass(
    ctracer: Path, grader: matrix.Grader, scenes: dict[str, Path], example: str, style: str, tmp_path: Path
) -> None:
    result = graded(ctracer, grader, scenes[example], style, tmp_path / "out.png")
    assert result["passed"], f"{style} on {example}: {result['reason']}"


@pytest.mark.parametrize("mistake", list(SHOWN_BY))
def test_each_mistake_fails_on_a_scene_that_shows_it(
    ctracer: Path, grader: matrix.Grader, scenes: dict[str, Path], mistake: str, tmp_path: Path
) -> None:
    result = graded(ctracer, grader, scenes[SHOWN_BY[mistake]], mistake, tmp_path / "out.png")
    assert not result["passed"], f"{mistake} passes on {SHOWN_BY[mistake]}"


def test_every_mistake_of_ctracer_is_held_to_a_scene(ctracer: Path) -> None:
    assert sorted(SHOWN_BY) == sorted(matrix.mistakes(ctracer))


def test_a_ppm_holds_the_pixels_of_the_png(ctracer: Path, scenes: dict[str, Path], tmp_path: Path) -> None:
    png = decode_png(matrix.render(ctracer, scenes["04_whitted"], tmp_path / "out.png", []))
    ppm = matrix.render(ctracer, scenes["04_whitted"], tmp_path / "out.ppm", ["--ppm"])
    header = b"P6\n160 120\n255\n"
    assert ppm.startswith(header)
    assert np.array_equal(np.frombuffer(ppm[len(header) :], dtype=np.uint8).reshape(png.shape), png)


@pytest.mark.parametrize("example", ["01_three_spheres", "06_orthographic", "05_mesh"])
def test_real_shadow_acne_is_named(
    ctracer: Path, grader: matrix.Grader, scenes: dict[str, Path], example: str, tmp_path: Path
) -> None:
    """A tracer that starts its rays on the surface (t > 0, no offset) speckles in its own pattern, sparse on a
    large lit surface: it lies between the reference and acne's far end, and is named for it."""
    image = matrix.render(ctracer, scenes[example], tmp_path / "out.png", matrix.switches("shadow-acne", {}))
    result = grader.grade(scenes[example], image, diagnose=True)
    assert not result["passed"]
    assert matrix.cell(result) == "FAIL(shadow-acne)", result["diagnosis"]


#: mistakes the diagnosis names as ctracer makes them, each on scenes that show it: (mistake, scene, the cell)
NAMED = [
    ("no-reflection", "04_whitted", "FAIL(no-reflection)"),
    ("no-reflection", "02_all_lights", "FAIL(no-reflection)"),
    ("no-reflection", "09_cornell_homework", "FAIL(no-reflection)"),
    # (light never leaves a glass ball either way: the image cannot tell them apart, and says both)
    ("no-refraction", "04_whitted", "FAIL(no-refraction, exit-normal-not-flipped)"),
    ("no-refraction", "09_cornell_homework", "FAIL(no-refraction, exit-normal-not-flipped)"),
    ("offset-too-large", "04_whitted", "FAIL(offset-too-large)"),
    ("offset-too-large", "09_cornell_homework", "FAIL(offset-too-large)"),
    # (ctracer offsets along a face's geometric normal; the mesh's shading normals are interpolated, and the
    # ladder along them leaves its image 0.15 % off at its exact amount: the geometric ladder names it)
    ("offset-too-large", "05_mesh", "FAIL(offset-too-large)"),
    # (C's (long long) cast of x / s: the cells either side of 0 merge on the orthographic floor)
    ("checker-truncated", "06_orthographic", "FAIL(checker-truncated)"),
    # (each sample i/nu of the way along an edge: the light moved half a cell towards its corner)
    ("area-samples-at-corners", "03_soft_shadows", "FAIL(area-samples-at-corners)"),
    ("area-samples-at-corners", "09_cornell_homework", "FAIL(area-samples-at-corners)"),
    # (u = unit(up) where the camera looks down: the rows sheared along the view)
    ("camera-up-as-given", "04_whitted", "FAIL(camera-up-as-given)"),
    ("camera-up-as-given", "06_orthographic", "FAIL(camera-up-as-given)"),
    # (the view's half-width h·H/W: a 4:3 image squeezed across to 3:4 of its width)
    ("aspect-inverted", "04_whitted", "FAIL(aspect-inverted)"),
    ("aspect-inverted", "09_cornell_homework", "FAIL(aspect-inverted)"),
    # (the smooth mesh's blend of vertex normals, a fifth shorter than 1 mid-face: its faces darker inside)
    ("normals-not-normalised", "05_mesh", "FAIL(normals-not-normalised)"),
    # (the mirror ball and the glass show black where the format shows the sky)
    ("bounce-miss-black", "04_whitted", "FAIL(bounce-miss-black)"),
    ("bounce-miss-black", "08_antialiased", "FAIL(bounce-miss-black)"),
]


@pytest.mark.parametrize(("mistake", "example", "expected"), NAMED)
def test_a_mistake_is_named_as_ctracer_makes_it(
    ctracer: Path,
    grader: matrix.Grader,
    scenes: dict[str, Path],
    mistake: str,
    example: str,
    expected: str,
    tmp_path: Path,
) -> None:
    scene = scenes[example]
    image = matrix.render(ctracer, scene, tmp_path / "out.png", matrix.switches(mistake, json.loads(scene.read_text())))
    result = grader.grade(scene, image, diagnose=True)
    assert matrix.cell(result) == expected, result["diagnosis"]["sentence"]


@pytest.mark.parametrize("example", ["04_whitted", "09_cornell_homework", "05_mesh"])
def test_an_offset_too_large_is_said_at_about_the_students_amount(
    ctracer: Path, grader: matrix.Grader, scenes: dict[str, Path], example: str, tmp_path: Path
) -> None:
    """ctracer's offset is its own (2e-2 of its scene's box: 0.086 on 04_whitted, between two of the ladder's
    rungs); the diagnosis says it in the scene's units, within a quarter of it."""
    scene = json.loads(scenes[example].read_text())
    image = matrix.render(ctracer, scenes[example], tmp_path / "out.png", matrix.switches("offset-too-large", scene))
    sentence = grader.grade(scenes[example], image, diagnose=True)["diagnosis"]["sentence"]
    said = float(sentence.split("about ", 1)[1].split(" ", 1)[0])
    assert abs(said / (2e-2 * matrix.scene_size(scene)) - 1) < 0.25, sentence
