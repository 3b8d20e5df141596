"""The confusion matrix's own yardstick (tests/offset_matrix.py): which mistakes an image shows.

A mistake counts as shown, and must then fail and be named, where undoing it changes the image by more than the
grade allows honest tracers; one that moves a few pixels by a level or two is not asked for.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import offset_matrix
import student

from schemas import load_scene
from service.images.grading import GROSS_LEVELS
from tracer import Renderer

WHITTED = Path(__file__).resolve().parent.parent / "examples" / "04_whitted.json"


def _whitted_small():  # noqa: ANN202
    return offset_matrix._sized(load_scene(WHITTED.read_bytes()), 64)


def test_normals_not_flipped_inside_closed_glass_is_not_shown():
    """On the Whitted example at 64 pixels across, normals not turned to face the ray change 50 pixels inside the
    glass ball by 1 level each: no rule can fail that without failing honest tracers, and a pair of it and an
    unseen mistake is not shown at all; one bounce too many (one pixel by 5 levels) beside a flipped image is
    not asked for, the flip is."""
    scene = _whitted_small()
    pair = ("specular-behind", "normals-not-flipped")
    image = student.render(scene, list(pair))
    reference = Renderer(scene).pixels()
    assert not np.array_equal(image, reference)  # it does change bytes: by a level
    assert not offset_matrix.visibly_different(image, reference)
    assert offset_matrix.shown(scene, pair) == set()
    assert offset_matrix.shown(scene, ("image-flipped", "depth-plus-one")) == {"image-flipped"}


def test_a_difference_the_grade_could_forgive_still_counts_as_shown():
    """Measured pixel by pixel: a one-pixel shift of the whole image, which the grade's neighbourhoods forgive,
    is a visible difference; so is one pixel grossly off; a few pixels within the fraction are not."""
    rng = np.random.default_rng(52)
    image = rng.integers(0, 256, size=(48, 64, 3), dtype=np.uint8)
    assert offset_matrix.visibly_different(np.roll(image, 1, axis=1), image)
    image[10, 10] = 0
    gross = image.copy()
    gross[10, 10, 0] = GROSS_LEVELS + 1
    assert offset_matrix.visibly_different(gross, image)
    few = image.copy()
    few[:1, :3] = np.where(image[:1, :3] > 127, image[:1, :3] - 60, image[:1, :3] + 60)  # 3 of 3072 by 60
    assert not offset_matrix.visibly_different(few, image)
