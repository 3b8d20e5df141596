"""Each light formula against numbers worked out by hand."""

import math

import numpy as np
import pytest

import schemas
from tracer.scene.lights import build_emitters, illuminate

ORIGIN = np.zeros(3)


def lit(em, points):
    """L, d and the intensity I = factor · color."""
    L, d, factor = illuminate(em, points)
    return L, d, factor[:, None] * em.color


def emitters(*lights):
    scene = schemas.validate_scene(
        {
            "camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
            "image": {"width": 1, "height": 1},
            "lights": list(lights),
        }
    )
    return build_emitters(scene.lights, ORIGIN)


def test_directional_light_points_against_its_travel():
    (em,) = emitters({"type": "directional", "color": [1, 2, 3], "direction": [0, -2, 0]})
    L, d, I = lit(em, np.zeros((2, 3)))
    np.testing.assert_allclose(L, [[0, 1, 0]] * 2)
    assert np.all(np.isinf(d))
    np.testing.assert_allclose(I, [[1, 2, 3]] * 2)


def test_point_light_attenuation():
    (em,) = emitters({"type": "point", "color": 1, "position": [3, 4, 0], "attenuation": [1, 0.1, 0.01]})
    L, d, I = lit(em, np.zeros((1, 3)))
    np.testing.assert_allclose(L, [[0.6, 0.8, 0]])
    np.testing.assert_allclose(d, [5])
    np.testing.assert_allclose(I, [[1 / 1.75] * 3])


def test_point_exactly_at_the_light_receives_nothing():
    (em,) = emitters({"type": "point", "color": 1, "position": [1, 1, 1], "attenuation": [0, 0, 1]})
    L, d, I = lit(em, np.array([[1.0, 1, 1], [1, 1, 3]]))
    assert np.all(np.isfinite(L))
    np.testing.assert_allclose(I, [[0, 0, 0], [0.25] * 3])


def spot_intensity(x):
    (em,) = emitters(
        {
            "type": "spot",
            "color": 1,
            "position": [0, 4, 0],
            "direction": [0, -1, 0],
            "cutoff": 30,
            "inner_cutoff": 10,
            "exponent": 2,
        }
    )
    return lit(em, np.array([[x, 0.0, 0]]))[2][0, 0]


def test_spot_inside_inner_cone_is_s_to_the_exponent():
    s = 4 / math.hypot(4, 0.5)  # 7.1° off axis
    assert spot_intensity(0.5) == pytest.approx(s**2, rel=1e-12)


def test_spot_between_cones_ramps_linearly():
    x = 4 * math.tan(math.radians(20))
    s = math.cos(math.radians(20))
    ramp = (s - math.cos(math.radians(30))) / (math.cos(math.radians(10)) - math.cos(math.radians(30)))
    assert spot_intensity(x) == pytest.approx(s**2 * ramp, rel=1e-9)


def test_spot_outside_cutoff_is_dark():
    assert spot_intensity(4 * math.tan(math.radians(31))) == 0


def test_area_light_is_a_grid_of_point_lights_at_cell_centres():
    ems = emitters(
        {
            "type": "area",
            "color": [4, 4, 4],
            "corner": [0, 2, 0],
            "edge_u": [2, 0, 0],
            "edge_v": [0, 0, 1],
            "samples": [2, 1],
            "attenuation": [1, 0, 0],
        }
    )
    positions = sorted(tuple(e.position) for e in ems)
    assert positions == [(0.5, 2, 0.5), (1.5, 2, 0.5)]
    for e in ems:
        np.testing.assert_allclose(e.color, [2, 2, 2])


@pytest.mark.parametrize("c", [1.0, 2.5, 1e-300])
def test_constant_attenuation_is_the_formula_at_every_distance(c):
    """An attenuation of (c, 0, 0) takes a shorter path; it gives what c + l·d + q·d² gives, bit for bit: at
    the light, next to it, far away, where the distance overflows, and at infinity (no light there)."""
    (em,) = emitters({"type": "point", "color": 1, "position": [0, 0, 0], "attenuation": [c, 0, 0]})
    points = np.array([[0, 0, 0], [1e-150, 0, 0], [0, 3, 4], [1e150, 0, 0], [0, -1e300, 0], [np.inf, 0, 0]])
    with np.errstate(all="ignore"):
        _, d, factor = illuminate(em, points)
        denom = c + 0.0 * d + 0.0 * d * d
        general = np.where((d > 0) & (denom > 0), 1.0 / np.where(denom > 0, denom, 1.0), 0.0)
    assert factor.tobytes() == general.tobytes()
    assert list(factor) == [0.0, 1.0 / c, 1.0 / c, 1.0 / c, 0.0, 0.0]
