"""The lighting kernel: one emitter's terms at hand-placed points, against the formulas worked out by hand; and
an area light, a loop of the same kernel, against its samples given as point lights."""

import numpy as np

import schemas
from tracer import Renderer
from tracer.exact.intersect import PLANE
from tracer.scene.lights import build_emitters
from tracer.scene.rays import Hits
from tracer.scene.variants import REFERENCE, VARIANTS
from tracer.shade.kernel import Kernel, Points


def floor_points(xs, shininess, dirs=None):
    """Hits on the floor y = 0 at x in ``xs``, seen along ``dirs`` (straight from above by default:
    D = (0, −1, 0)); N = (0, 1, 0)."""
    n = len(xs)
    point = np.zeros((n, 3))
    point[:, 0] = xs
    normal = np.tile([0.0, 1.0, 0.0], (n, 1))
    dirs = np.tile([0.0, -1.0, 0.0], (n, 1)) if dirs is None else np.asarray(dirs, dtype=np.float64)
    hit = Hits(
        np.ones(n),
        np.full(n, PLANE, dtype=np.int8),
        np.zeros(n, dtype=np.int64),
        point,
        normal.copy(),
        np.zeros((n, 2)),
        np.zeros(n, dtype=np.int64),
    )
    return Points(hit, normal, dirs, np.ones(n), np.zeros(n), np.full(n, float(shininess)))


def kernel_of(xs, shininess, options=REFERENCE, dirs=None):
    scene = schemas.validate_scene(
        {
            "camera": {"position": [0, 5, 0], "look_at": [0, 0, 0], "up": [0, 0, -1]},
            "image": {"width": 1, "height": 1},
            "materials": {"m": {}},
            "objects": [{"type": "plane", "material": "m", "point": [0, 0, 0], "normal": [0, 1, 0]}],
        }
    )
    world = Renderer(scene).world
    at = floor_points(xs, shininess, dirs)
    at.nv = -np.sum(at.normal * at.dirs, axis=1)
    return Kernel(world, options, at)


def point_light(position, attenuation=(1, 0, 0)):
    scene = schemas.validate_scene(
        {
            "camera": {"position": [0, 5, 0], "look_at": [0, 0, 0], "up": [0, 0, -1]},
            "image": {"width": 1, "height": 1},
            "lights": [{"type": "point", "color": 1, "position": list(position), "attenuation": list(attenuation)}],
        }
    )
    return build_emitters(scene.lights, np.zeros(3))[0]


def test_point_light_terms_are_the_phong_weights():
    kernel = kernel_of([0.0, 3.0], shininess=2)
    reach = kernel.reach(point_light([0, 4, 0], attenuation=(1, 0.25, 0)), holds=False)
    wd, ws = kernel.terms(reach)
    # at x = 0: L = N, d = 4, f = 1/2, R·V = 1; at x = 3: L = (−3, 4, 0)/5, d = 5, f = 1/2.25
    # R·V = 2(N·L)(N·V) + L·D = 2·0.8·1 − 0.8 = 0.8
    np.testing.assert_allclose(wd, [0.5 * 1.0, 0.8 / 2.25])
    np.testing.assert_allclose(ws, [0.5 * 1.0, 0.8**2 / 2.25])


def test_a_light_below_the_surface_gives_no_weight_and_no_terms():
    kernel = kernel_of([0.0], shininess=0)
    reach = kernel.reach(point_light([0, -1, 0]), holds=False)
    assert not reach.lit.any()
    wd, ws = kernel.terms(reach)
    assert wd.tolist() == [0.0] and ws.tolist() == [0.0]


def test_specular_is_zero_where_r_dot_v_is_not_positive_even_at_shininess_zero():
    # a light low on the −x side: R leaves low on the +x side; seen from above R·V > 0, seen from low on the −x
    # side (a ray travelling +x) R·V < 0
    grazing = np.array([1.0, -0.2, 0.0]) / np.sqrt(1.04)
    kernel = kernel_of([0.0, 0.0], shininess=0, dirs=[[0.0, -1.0, 0.0], grazing])
    wd, ws = kernel.terms(kernel.reach(point_light([-1, 0.1, 0]), holds=False))
    assert ws[0] == 1.0 and ws[1] == 0.0
    assert wd[1] > 0


def test_light_from_behind_variant_keeps_the_diffuse_term_non_negative():
    options = VARIANTS["specular-behind"][0]
    kernel = kernel_of([0.0], shininess=1, options=options)
    reach = kernel.reach(point_light([0, -1, 0]), holds=False)
    assert reach.lit.all() and not reach.facing.any()
    wd, _ = kernel.terms(reach)
    assert wd.tolist() == [0.0]


def area_scene(samples, as_points):
    corner, eu, ev = np.array([-1.0, 3.0, -1.0]), np.array([2.0, 0, 0]), np.array([0, 0, 2.0])
    nu, nv = samples
    if as_points:
        lights = [
            {
                "type": "point",
                "color": 1.0 / (nu * nv),
                "position": (corner + (i + 0.5) / nu * eu + (j + 0.5) / nv * ev).tolist(),
            }
            for i in range(nu)
            for j in range(nv)
        ]
    else:
        lights = [
            {
                "type": "area",
                "color": 1,
                "corner": corner.tolist(),
                "edge_u": eu.tolist(),
                "edge_v": ev.tolist(),
                "samples": [nu, nv],
            }
        ]
    return schemas.validate_scene(
        {
            "camera": {"position": [0, 4, 6], "look_at": [0, 0, 0]},
            "image": {"width": 24, "height": 18},
            "materials": {"m": {"ambient": 0.1, "diffuse": 0.6, "specular": 0.4, "shininess": 8}},
            "objects": [
                {"type": "plane", "material": "m", "point": [0, 0, 0], "normal": [0, 1, 0]},
                {"type": "sphere", "material": "m", "center": [0.3, 0.7, 0], "radius": 0.6},
            ],
            "lights": lights,
        }
    )


def test_an_area_light_shades_as_its_samples_given_as_point_lights():
    area = Renderer(area_scene((3, 2), False)).chunk(0, 24 * 18)
    points = Renderer(area_scene((3, 2), True)).chunk(0, 24 * 18)
    assert np.abs(area - points).max() < 1e-12  # (its colour added once, theirs six times: rounding apart)
