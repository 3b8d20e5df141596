"""The stored image's mistakes (service/diagnosis/stored.py): tried on the reference's pixels, with no render."""

import numpy as np
import pytest
from test_compose import small

from service.diagnosis.stored import image_level, outer, undone
from tracer import Renderer
from tracer.scene.variants import Options


def test_undone_inverts_the_stored_images_flips_and_channel_swap():
    image = np.random.default_rng(3).integers(0, 256, (6, 5, 3), dtype=np.uint8)
    names = ("image-flipped", "camera-left-handed", "channels-swapped")
    assert np.array_equal(undone(outer(image, names), names), image)
    grey = outer(image, ("grayscale",))
    assert np.array_equal(grey, Options(grayscale=True).stored(image))


@pytest.mark.parametrize(
    "names", [("camera-left-handed",), ("grayscale",), ("channels-swapped",), ("image-flipped", "channels-swapped")]
)
def test_image_level_mistakes_are_found_on_the_references_pixels(names):
    reference = Renderer(small("01_three_spheres")).pixels()
    assert set(image_level(reference, outer(reference, names))) == set(names)
    assert image_level(reference, reference) == {}
