"""The held-out check (bench/heldout.py) on a few cases: the second student's images, which the diagnosis was not
tuned on, graded and diagnosed as ``phongray grade`` does it."""

import pytest

import schemas
from bench.heldout import Case, case, named
from bench.scenes import example
from tracer import Renderer


@pytest.fixture(scope="module")
def spheres():
    scene = schemas.validate_scene(example("01_three_spheres", 64, 48))
    return scene, Renderer(scene).pixels()


@pytest.mark.parametrize(
    "made", [(), ("grayscale",), ("camera-left-handed",), ("no-shadows", "blinn-phong"), ("no-shadows", "gamma")]
)
def test_the_second_students_images_are_named(spheres, made):
    scene, reference = spheres
    found = case(scene, reference, "01_three_spheres", made, None, made)
    assert found.ok, found
    if made:
        assert not found.passed and set(made) <= set(found.named)
    else:
        assert found.passed and not found.sentence.startswith("Likely")


def test_a_case_is_named_only_when_every_visible_mistake_is():
    assert not Case("x", ("a", "b"), ("a", "b"), False, ("a",), "").ok
    assert Case("x", ("a", "b"), ("a",), False, ("a",), "").ok
    assert not Case("x", (), (), False, (), "").ok and Case("x", (), (), True, (), "PASS").ok
    assert named({"causes": [{"variant": "a", "passes": False}], "closest": True}) == ("a",)
    assert named({"causes": [{"variant": "a", "passes": False}], "closest": False}) == ()
    # (closest to a combination: "comes closest to the reference rendered with both" names both)
    closest_pair = [{"variant": "a", "passes": False, "together": ["b"]}, {"variant": "b", "passes": False}]
    assert named({"causes": closest_pair, "closest": True}) == ("a", "b")
