"""PPM submissions (service/images/ppm.py): P3 and P6 graded as their PNG is, everywhere a PNG is; hostile headers
refused before a pixel is read."""

import json
import tracemalloc

import numpy as np
import pytest
from fastapi.testclient import TestClient

import schemas
import tracer
from service.http.app import create_app
from service.images import grading
from service.images.ppm import HEADER_LIMIT, header
from service.settings import Settings
from service.work import pipeline

from helpers import SCENES, scene_dict


def p6(pixels: np.ndarray, head: bytes = b"") -> bytes:
    h, w, _ = pixels.shape
    return b"P6\n" + head + f"{w} {h}\n255\n".encode() + pixels.tobytes()


def p3(pixels: np.ndarray) -> bytes:
    """As *Ray Tracing in One Weekend* prints it: a header of three lines, a pixel's values on a line."""
    h, w, _ = pixels.shape
    lines = [f"{r} {g} {b}" for r, g, b in pixels.reshape(-1, 3)]
    return ("P3\n" + f"{w} {h}\n255\n" + "\n".join(lines) + "\n").encode()


@pytest.fixture(scope="module")
def rendered():
    """A scene, its reference PNG, and a failing submission (a light left out) as PNG, P3 and P6."""
    data = scene_dict("02_all_lights")
    data["image"].update(width=96, height=72)
    reference = tracer.encode_png(tracer.render(schemas.validate_scene(data)))
    wrong = tracer.render(schemas.validate_scene({**data, "lights": data["lights"][:-1]}))
    return data, reference, {"png": tracer.encode_png(wrong), "p3": p3(wrong), "p6": p6(wrong)}


def test_p3_and_p6_decode_to_the_pixels_written():
    px = np.random.default_rng(5).integers(0, 256, (9, 13, 3), dtype=np.uint8)
    for data in (p3(px), p6(px), p6(px, b"# made by a student's tracer\n")):
        assert np.array_equal(grading.read_submission(data, (13, 9)), px)
    odd = b"P3 2 1\t# width and height\n255 0 1 2\n3\r\n4\t\t5\n"  # any white space, a comment in the header
    assert grading.read_submission(odd, (2, 1)).tolist() == [[[0, 1, 2], [3, 4, 5]]]


def test_a_ppm_grades_as_its_png_does(rendered):
    data, reference, images = rendered
    grades = {k: pipeline.grade_png(reference, image, 2.0, 0.001).grade.as_dict() for k, image in images.items()}
    assert grades["png"]["passed"] is False and grades["p3"] == grades["png"] == grades["p6"]


def test_over_http_a_ppm_grades_as_its_png_does(rendered):
    data, _, images = rendered
    api = TestClient(create_app(Settings()))
    answers = {
        k: api.post(
            "/grade", data={"scene": json.dumps(data), "diagnose": "false"}, files={"image": ("i", image, "x/y")}
        )
        for k, image in images.items()
    }
    assert {k: a.status_code for k, a in answers.items()} == {"png": 200, "p3": 200, "p6": 200}
    assert answers["png"].json()["passed"] is False
    assert answers["p3"].json() == answers["png"].json() == answers["p6"].json()
    broken = api.post("/grade", data={"scene": json.dumps(data)}, files={"image": ("i", b"P6 96 72 1023\n", "x/y")})
    assert broken.status_code == 422 and "maxval 1023" in broken.json()["detail"]


@pytest.mark.parametrize(
    ("data", "words"),
    [
        (b"P6 4 3 65535\n" + b"\0" * 72, "maxval 65535; only 8-bit PPMs (maxval 255)"),
        (b"P6 4 3 0\n", "maxval 0"),
        (b"P6\n#" + b"x" * HEADER_LIMIT, f"header is longer than {HEADER_LIMIT} bytes"),
        (b"P6 " + b"9" * 30 + b" 3 255\n", "width has more than 9 digits"),
        (b"P6 4 3", "ends in its PPM header"),
        (b"P6 4 x 255\n", "byte 5 is not its height"),
        (b"P6 4 3 255\n" + b"\1" * 35, "pixel data ends early (35 of 36 bytes)"),
        (b"P6 4 3 255\n" + b"\1" * 36 + b"done.\n", "5 bytes after its PPM pixels"),
        (b"P3 4 3 255\n" + b"1 " * 35, "truncated: its P3 pixel data holds 35 values"),
        (b"P3 4 3 255\n" + b"1 " * 37, "values after its pixels"),
        (b"P3 4 3 255\n" + b"1 " * 35 + b"256\n", "the value 256, above its maxval 255"),
        (b"P3 4 3 255\n" + b"1 " * 35 + b"0001\n", "a value of 4 digits"),
        (b"P3 4 3 255\n" + b"1 " * 35 + b"-1\n", "something other than numbers"),
        (b"P5 4 3 255\n", "a PGM (greyscale Netpbm); PNG or PPM required"),
    ],
)
def test_a_broken_or_hostile_ppm_is_refused_with_its_reason(data, words):
    with pytest.raises(grading.ImageError, match=None) as exc:
        grading.read_submission(data, (4, 3))
    assert words in str(exc.value)


def test_trailing_white_space_is_no_fault():
    px = np.zeros((3, 4, 3), np.uint8)
    assert grading.read_submission(p6(px) + b"\n\n", (4, 3)).shape == (3, 4, 3)


def test_the_size_is_checked_on_the_header_before_any_pixel_is_read():
    huge = b"P6 100000 100000 255\n" + b"\0" * 64  # 3e10 bytes of pixels declared
    tracemalloc.start()
    with pytest.raises(grading.ImageError, match="image is 100000×100000 pixels, the scene is 4×3"):
        grading.read_submission(huge, (4, 3))
    with pytest.raises(grading.ImageError, match="more than the 16777216"):
        grading.declared_size(huge, 4096 * 4096)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 1 << 20
    assert header(huge).width == 100000


def test_a_reference_given_to_compare_may_be_a_ppm(tmp_path, capsys):
    from service.cli import main

    px = tracer.render(schemas.load_scene((SCENES / "01_three_spheres.json").read_bytes()))
    (tmp_path / "ref.ppm").write_bytes(p6(px))
    (tmp_path / "img.ppm").write_bytes(p3(px))
    assert main(["compare", str(tmp_path / "ref.ppm"), str(tmp_path / "img.ppm")]) == 0
    assert capsys.readouterr().out.startswith("PASS")


def test_a_class_of_ppm_submissions_is_graded_as_its_pngs(tmp_path, rendered):
    from service.classgrade import ClassRun, grade_class

    data, _, images = rendered
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "lights.json").write_text(json.dumps(data))
    for student, (kind, name) in {
        "ann": ("png", "lights.png"),
        "bob": ("p3", "Lights.ppm"),
        "cy": ("p6", "hw/lights.ppm"),
    }.items():
        (tmp_path / "subs" / student / name).parent.mkdir(parents=True)
        (tmp_path / "subs" / student / name).write_bytes(images[kind])
    outcome = grade_class(ClassRun(tmp_path / "scenes", tmp_path / "subs", tmp_path / "report", jobs=1, diagnose=False))
    rows = {r["student"]: r for r in outcome.rows}
    numbers = [
        {k: rows[s][k] for k in ("status", "fraction_off_nearby", "rmse", "reason")} for s in ("ann", "bob", "cy")
    ]
    assert numbers[0]["status"] == "fail" and numbers[0] == numbers[1] == numbers[2]
    assert rows["cy"]["file"] == "hw/lights.ppm"
    copies = [(tmp_path / "report" / "submissions" / s / "lights.png").read_bytes() for s in ("ann", "bob", "cy")]
    assert (
        copies[1] == copies[2]
        and grading.read_submission(copies[1], (96, 72)).tolist()
        == grading.read_submission(copies[0], (96, 72)).tolist()
    )


def test_a_p3_is_read_a_block_at_a_time_with_no_value_cut_in_two(monkeypatch):
    import service.images.ppm

    px = np.random.default_rng(9).integers(0, 256, (7, 11, 3), dtype=np.uint8)
    data = p3(px)
    for block in (1, 2, 3, 5, 64):  # (a block of 1 to 3 bytes may hold no white space: it ends where it must)
        monkeypatch.setattr(service.images.ppm, "BLOCK", block)
        assert np.array_equal(grading.read_submission(data, (11, 7)), px), block
    monkeypatch.setattr(service.images.ppm, "BLOCK", 4)
    with pytest.raises(grading.ImageError, match="a value of 4 digits"):
        grading.read_submission(b"P3 1 1 255\n1 2 0003\n", (1, 1))


def test_a_large_p3_is_decoded_in_bounded_memory():
    """A P3 of 1280×1024 (13 MiB of text): its temporaries are a byte per byte of text and a few MiB a block,
    not the ~190 MiB that reading the whole file's values at once takes."""
    data = b"P3 1280 1024 255\n" + b" ".join([b"255"] * (1280 * 1024 * 3)) + b"\n"
    tracemalloc.start()
    pixels = grading.read_submission(data, (1280, 1024))
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert pixels.shape == (1024, 1280, 3) and int(pixels.min()) == 255
    assert peak < len(data) + (24 << 20), peak
