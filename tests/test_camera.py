"""Primary rays follow the contract's pixel formula."""

import math

import numpy as np

import schemas
from tracer.scene.camera import CameraRays


def camera(**cam):
    scene = schemas.validate_scene(
        {
            "camera": {"position": [0, 0, 0], "look_at": [0, 0, -1], **cam},
            "image": {"width": 4, "height": 2, "samples": 2},
        }
    )
    return CameraRays(scene.camera, scene.image, np.zeros(3))


def test_perspective_subsample_directions():
    origins, dirs = camera(fov=90).rays(0, 1)
    assert origins.shape == (4, 3) and np.all(origins == 0)
    # pixel (0, 0), sub-sample (a, b) = (1, 0): sx = 0.75/4, sy = 0.25/2
    sx, sy = 0.75 / 4, 0.25 / 2
    x, y = (2 * sx - 1) * 2 * math.tan(math.radians(45)), (1 - 2 * sy) * 1.0
    expected = np.array([x, y, -1]) / math.sqrt(x * x + y * y + 1)
    np.testing.assert_allclose(dirs[1], expected, rtol=1e-14)


def test_orthographic_rays_are_parallel_and_offset():
    origins, dirs = camera(type="orthographic", height=4).rays(7, 8)
    np.testing.assert_allclose(dirs, [[0, 0, -1]] * 4)
    # last pixel (3, 1), sub-sample (0, 0): sx = 3.25/4, sy = 1.25/2, h = 2
    np.testing.assert_allclose(origins[0], [(2 * 3.25 / 4 - 1) * 2 * 2, (1 - 2 * 1.25 / 2) * 2, 0])


def test_up_vector_sets_the_roll():
    origins, dirs = camera(up=[1, 0, 0], fov=90).rays(0, 1)
    # with up = +x, screen-up is +x, so the top-left pixel looks towards +x
    assert np.all(dirs[:, 0] > 0)
