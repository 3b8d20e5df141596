"""Scenes built to break careless numerics, checked against the float64 brute force of tests/reference.py.

For each scene, the first surface of every primary ray, every shadow
decision from those hits and every pixel must agree with the brute force
wherever it is clear (:func:`fuzz.compare`), and the images must keep the
invariances the contract promises.
"""

import copy

import numpy as np
import pytest

import schemas
from tracer import Renderer, encode_png

import fuzz
from helpers import differing, scaled, translated

MATS = {
    "m": {"diffuse": 0.7},
    "glass": {"transmittance": 0.9, "reflectance": 0.1, "ior": 1.5},
    "mirror": {"reflectance": 0.8},
    "red": {"diffuse": [0.9, 0.1, 0.1], "specular": 0.9, "shininess": 20},
}


def scene(objects, lights, camera, width=64, height=48, **image):
    return {
        "camera": camera,
        "image": {"width": width, "height": height, **image},
        "materials": MATS,
        "objects": objects,
        "lights": lights,
    }


def mesh_floor(size, y=0.0, n=4):
    xs = np.linspace(-size, size, n + 1)
    verts = [[float(x), y, float(z)] for z in xs for x in xs]
    faces = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            faces += [[a, a + n + 2, a + 1], [a, a + n + 1, a + n + 2]]
    return {"type": "mesh", "material": "m", "vertices": verts, "faces": faces}


def box(lo, hi, material="m"):
    corners = [[(lo, hi)[x][0], (lo, hi)[y][1], (lo, hi)[z][2]] for x in (0, 1) for y in (0, 1) for z in (0, 1)]
    faces = [
        [0, 1, 3],
        [0, 3, 2],
        [4, 6, 7],
        [4, 7, 5],
        [0, 4, 5],
        [0, 5, 1],
        [2, 3, 7],
        [2, 7, 6],
        [0, 2, 6],
        [0, 6, 4],
        [1, 5, 7],
        [1, 7, 3],
    ]
    return {"type": "mesh", "material": material, "vertices": corners, "faces": faces}


def tilted_floor(n=4, size=2.0):
    """A flat mesh in the plane y = 0.3 x + 0.2 z: its faces' normals and points round, its plane does not."""
    xs = np.linspace(-size, size, n + 1)
    out = mesh_floor(size, 0.0, n)
    out["vertices"] = [[float(x), float(0.3 * x + 0.2 * z), float(z)] for z in xs for x in xs]
    out["material"] = "red"
    return out


LOOK_DOWN = {"position": [0, 3, 3], "look_at": [0, 0, 0], "fov": 50}
HARD = {
    "point light a few thousandths above a floor, sliver above it": scene(
        [
            mesh_floor(4),
            {"type": "triangle", "material": "m", "vertices": [[-1, 0.0005, 0.6], [1, 0.0005, 0.6], [0, 0.0005, 0.65]]},
        ],
        [{"type": "point", "color": 1, "position": [0.1, 0.003, 1.0]}],
        LOOK_DOWN,
    ),
    "area light lying in a mesh floor": scene(
        [mesh_floor(4), {"type": "sphere", "material": "m", "center": [0, 0.5, 0], "radius": 0.5}],
        [
            {
                "type": "area",
                "color": 2,
                "corner": [-1, 0, 1],
                "edge_u": [2, 0, 0],
                "edge_v": [0, 0, 1],
                "samples": [3, 3],
            }
        ],
        LOOK_DOWN,
    ),
    "lights in the plane of an orthographic camera's middle row": scene(
        [
            {"type": "plane", "material": "m", "point": [0, 0, 0], "normal": [0, 1, 0]},
            {"type": "sphere", "material": "m", "center": [0, 0, -2], "radius": 0.7},
        ],
        [{"type": "point", "color": 1, "position": [2, 0, 0]}, {"type": "point", "color": 1, "position": [-2, 0, -4]}],
        {"type": "orthographic", "position": [0, 0, 5], "look_at": [0, 0, 0], "height": 3},
        height=49,
    ),
    "glass and contact shadows with look_at a million units beyond": scene(
        [
            mesh_floor(3),
            {"type": "sphere", "material": "glass", "center": [0, 0.4, 0], "radius": 0.4},
            box([0.6, 0, -0.3], [0.9, 0.3, 0.0]),
        ],
        [{"type": "point", "color": 1, "position": [1, 3, 2]}],
        {"position": [0, 1.5, 3], "look_at": [0, 1.5 - 0.4 * 1e6, 3 - 1e6], "fov": 45},
        max_depth=4,
    ),
    "triangle edges at a 1e-5 degree field of view": scene(
        [{"type": "triangle", "material": "m", "vertices": [[-1, -1, 0], [1, -1, 0], [0.3, 1, 0]]}],
        [{"type": "directional", "color": 1, "direction": [0, 0, -1]}],
        {"position": [0.65, 0, 10], "look_at": [0.65, 0, 0], "fov": 1e-5},
    ),
    "tilted ground triangle reaching 1e5 away": scene(
        [
            {
                "type": "triangle",
                "material": "m",
                "vertices": [[-1e5, -1e5 * 0.05, 1e5], [1e5, 1e5 * 0.05, 1e5], [0, 0, -1e5]],
            },
            {"type": "sphere", "material": "m", "center": [0, 0.3, 0], "radius": 0.3},
            {"type": "sphere", "material": "m", "center": [0.8, 0.2, 0.4], "radius": 0.15},
        ],
        [{"type": "point", "color": 1, "position": [-3, 0.5, -1]}],
        LOOK_DOWN,
    ),
    "glass shell 1e-6 thick": scene(
        [
            {"type": "sphere", "material": "glass", "center": [0, 0, 0], "radius": 1.0},
            {"type": "sphere", "material": "glass", "center": [0, 0, 0], "radius": 1.0 + 1e-6},
            {"type": "plane", "material": "m", "point": [0, -1.2, 0], "normal": [0, 1, 0]},
        ],
        [{"type": "point", "color": 1, "position": [2, 3, 2]}],
        {"position": [0, 0.5, 3.5], "look_at": [0, 0, 0]},
        max_depth=5,
    ),
    "column of 150 spheres along an orthographic camera's axis": scene(
        [
            {"type": "sphere", "material": "m", "center": [0.02 * (k % 3), 0, -0.1 * k], "radius": 0.06}
            for k in range(150)
        ],
        [{"type": "directional", "color": 1, "direction": [0, -1, -1]}],
        {"type": "orthographic", "position": [0, 0, 5], "look_at": [0, 0, 0], "height": 0.3},
    ),
    "light inside a sphere of radius 1e-5 and a closed box of 2e-5": scene(
        [
            {"type": "plane", "material": "m", "point": [0, 0, 0], "normal": [0, 1, 0]},
            {"type": "sphere", "material": "m", "center": [-1, 1, 0], "radius": 1e-5},
            box([1 - 1e-5, 1 - 1e-5, -1e-5], [1 + 1e-5, 1 + 1e-5, 1e-5]),
        ],
        [{"type": "point", "color": 1, "position": [-1, 1, 0]}, {"type": "point", "color": 1, "position": [1, 1, 0]}],
        LOOK_DOWN,
    ),
    "shade 4e-6 under a light": scene(
        [
            {"type": "plane", "material": "m", "point": [0, 0, 0], "normal": [0, 1, 0]},
            {
                "type": "triangle",
                "material": "m",
                "vertices": [[-0.01, 1 - 4e-6, -0.01], [0.01, 1 - 4e-6, -0.01], [0, 1 - 4e-6, 0.01]],
            },
        ],
        [{"type": "point", "color": 1, "position": [0, 1, 0]}],
        {"position": [0, 3, 0.5], "look_at": [0, 0, 0]},
    ),
    "camera exactly on a floor and on a sphere": scene(
        [
            {"type": "plane", "material": "m", "point": [0, 0, 0], "normal": [0, 1, 0]},
            {"type": "sphere", "material": "m", "center": [0, 1, -3], "radius": 0.5},
        ],
        [{"type": "point", "color": 1, "position": [0, 3, 0]}],
        {"position": [0, 0, 0], "look_at": [0, -0.2, -1]},
    ),
    # nested and enclosing surfaces, which a walk that skips past a proxy's box drops
    "balls inside a room sphere around the camera": scene(
        [
            {"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 6},
            *[
                {"type": "sphere", "material": "red", "center": c, "radius": 0.6}
                for c in ([0, 0, -2], [1.5, -1, -1], [-1.8, 0.8, -2.5], [0.5, 1.5, 1])
            ],
        ],
        [{"type": "point", "color": 1, "position": [0, 3, 1]}],
        {"position": [0, 0.5, 3], "look_at": [0, 0, -2]},
    ),
    "glass balls with opaque cores, seen from outside": scene(
        [
            *[{"type": "sphere", "material": "glass", "center": [x, 0, 0], "radius": 1} for x in (-1.1, 1.1)],
            *[{"type": "sphere", "material": "red", "center": [x, 0.1, 0], "radius": 0.35} for x in (-1.1, 1.1)],
            {"type": "plane", "material": "m", "point": [0, -1, 0], "normal": [0, 1, 0]},
        ],
        [{"type": "point", "color": 1, "position": [2, 3, 3]}],
        {"position": [0, 0.5, 4.5], "look_at": [0, 0, 0]},
        max_depth=4,
    ),
    "concentric glass shells round an opaque core, in a room": scene(
        [
            *[{"type": "sphere", "material": "glass", "center": [0, 0, 0], "radius": r} for r in (1, 0.45, 0.2)],
            {"type": "sphere", "material": "red", "center": [0, 0, 0], "radius": 0.08},
            {"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 8},
        ],
        [{"type": "point", "color": 1, "position": [2, 3, 3]}],
        {"position": [0, 0, 2.2], "look_at": [0, 0, 0], "fov": 40},
        max_depth=8,
    ),
    "a point light inside a glass ball inside a room": scene(
        [
            {"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 8},
            {"type": "sphere", "material": "glass", "center": [0, 1, 0], "radius": 1},
            {"type": "sphere", "material": "red", "center": [2, -1, 0], "radius": 0.8},
        ],
        [{"type": "ambient", "color": 0.05}, {"type": "point", "color": 1, "position": [0, 1, 0]}],
        {"position": [0, 0, 6], "look_at": [0, 0, 0]},
        max_depth=2,
    ),
    "lights at the centres of spheres, camera inside a dome": scene(
        [
            {"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 10},
            {"type": "sphere", "material": "red", "center": [0, 0, -3], "radius": 1},
            {"type": "sphere", "material": "m", "center": [3, 1, -2], "radius": 0.7},
        ],
        [
            {"type": "point", "color": 1, "position": [0, 0, -3]},
            {"type": "point", "color": 1, "position": [3, 1, -2]},
            {"type": "point", "color": 0.5, "position": [-2, 4, 2]},
        ],
        {"position": [0, 1, 5], "look_at": [0, 0, -3], "fov": 80},
    ),
    # lights in the planes of flat surfaces: N·L is 0 there, never rounding noise that lets specular glint
    "point lights at a mesh vertex and on a ridge edge, a directional light along the floor": scene(
        [
            {
                "type": "mesh",
                "material": "red",
                "vertices": [[-2, 0, -2], [2, 0, -2], [2, 0, 2], [-2, 0, 2], [0, 1, 0]],
                "faces": [[0, 4, 1], [1, 4, 2], [2, 4, 3], [3, 4, 0]],
            },
            {"type": "plane", "material": "red", "point": [0, -0.5, 0], "normal": [0, 1, 0]},
        ],
        [
            {"type": "point", "color": 1, "position": [0, 1, 0]},
            {"type": "point", "color": 1, "position": [1, 0.5, -1]},
            {"type": "directional", "color": 1, "direction": [1, 0, 0.5]},
        ],
        {"position": [1.5, 2.5, 4], "look_at": [0, 0, 0]},
    ),
    "a point light at a vertex of a tilted flat mesh": scene(
        [
            tilted_floor(),
            *[
                {"type": "sphere", "material": "red", "center": c, "radius": 0.3}
                for c in ([0, 1, 0], [1, 1, 1], [-1, 1, 1])
            ],
        ],
        [{"type": "ambient", "color": 0.1}, {"type": "point", "color": 1, "position": tilted_floor()["vertices"][7]}],
        {"position": [1.5, 3.5, 5], "look_at": [0, 0, 0]},
    ),
    # far away, huge and tiny: the precision near the eye stays the eye's own
    "a sun 1e8 away and a glass shell 1e-6 thick": scene(
        [
            {"type": "sphere", "material": "glass", "center": [0, 0, 0], "radius": 1.0},
            {"type": "sphere", "material": "glass", "center": [0, 0, 0], "radius": 1.0 - 1e-6},
            {"type": "sphere", "material": "red", "center": [0, 0, 0], "radius": 0.3},
            {"type": "plane", "material": "m", "point": [0, -1.2, 0], "normal": [0, 1, 0]},
        ],
        [{"type": "point", "color": 1, "position": [1e8, 1e8, 0.5e8]}],
        {"position": [0, 0.5, 3.5], "look_at": [0, 0, 0]},
        max_depth=5,
    ),
    "camera on a sphere looking in": scene(
        [{"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 1}],
        [{"type": "point", "color": 1, "position": [0, 0.5, 0]}],
        {"position": [0, 0, 1], "look_at": [0, 0, 0]},
    ),
}


@pytest.mark.parametrize("name", sorted(HARD))
def test_hits_shadows_and_pixels_agree_with_a_float64_brute_force(name):
    agrees_with_brute_force(HARD[name])


def agrees_with_brute_force(data, clear=0.9):
    """Asserts that every primary ray's first surface (and its t), every shadow decision from those hits and
    every pixel of ``data`` agree with the brute force of :mod:`reference`, wherever it is clear, and that it
    is clear on at least the fraction ``clear`` of the pixels (so that the comparison says something)."""
    out = fuzz.compare(-1, data)
    assert not out.bad, f"{dict(out.disagreed)} disagree: " + "; ".join(out.examples)
    pixels = data["image"]["width"] * data["image"]["height"]
    assert out.compared["pixel"] >= clear * pixels, f"the brute force is clear on {out.compared['pixel']} pixels"
    assert out.compared["hit"] > 0


def render(data, **kw):
    return Renderer(schemas.validate_scene(data)).pixels(**kw)


def test_a_light_inside_a_tiny_sphere_or_box_does_not_leak():
    img = render(HARD["light inside a sphere of radius 1e-5 and a closed box of 2e-5"])
    ambient_only = render({**HARD["light inside a sphere of radius 1e-5 and a closed box of 2e-5"], "lights": []})
    assert np.array_equal(img, ambient_only)


def test_a_shade_4e6_under_a_light_casts_its_shadow():
    data = HARD["shade 4e-6 under a light"]
    img = render(data)
    open_sky = render({**data, "objects": data["objects"][:1]})
    assert np.sum(np.any(img != open_sky, axis=2)) > 20  # the shadow on the floor, straight below


def test_eye_on_a_floor_does_not_see_the_floor():
    img = render(HARD["camera exactly on a floor and on a sphere"])
    assert np.all(img[-1] == 0)  # below the horizon: nothing but background (the floor starts at the eye)


def test_edge_at_a_tiny_field_of_view_lands_on_its_exact_column():
    data = HARD["triangle edges at a 1e-5 degree field of view"]
    img = render(data)
    w, h = data["image"]["width"], data["image"]["height"]
    half = np.tan(np.radians(data["camera"]["fov"]) / 2) * 10  # world half-height of the view at the triangle
    x = 0.65 + (2 * (np.arange(w) + 0.5) / w - 1) * w / h * half  # world x of each pixel column's centre
    edge = 0.3 + (1 - 0) * (1 - 0.3) / 2  # right edge from (1, -1) to (0.3, 1), at y = 0
    lit = img[h // 2, :, 0] > 0
    assert np.array_equal(lit, x < edge)


@pytest.mark.parametrize(
    "name",
    [
        "glass and contact shadows with look_at a million units beyond",
        "tilted ground triangle reaching 1e5 away",
        "glass shell 1e-6 thick",
        "point light a few thousandths above a floor, sliver above it",
    ],
)
def test_invariances_give_identical_bytes(name):
    data = HARD[name]
    first = encode_png(render(data))
    cam = data["camera"]
    p, la = np.array(cam["position"], float), np.array(cam["look_at"], float)
    for k in (1e-3, 1e3, 1e6):  # look_at moved along the view ray
        moved = copy.deepcopy(data)
        moved["camera"]["look_at"] = (p + (la - p) / np.linalg.norm(la - p) * k).tolist()
        assert encode_png(render(moved)) == first
    for factor in (1e-30, 1e-10, 1e10, 1e30):
        assert differing(render(scaled(data, factor)), render(data), tolerance=0) <= 0.001
    assert differing(render(translated(data, (1e6, -1e6, 1e6))), render(data), tolerance=0) <= 0.001


def test_column_of_spheres_shows_the_nearest_not_background():
    img = render(HARD["column of 150 spheres along an orthographic camera's axis"])
    h, w = img.shape[:2]
    assert np.all(img[h // 2, w // 2] > 0)


def test_a_fan_of_8000_slivers_round_one_vertex_renders_and_agrees_with_the_brute_force():
    # every sliver's box holds the shared vertex: a part of a cell there holds them all, which is slow, not wrong
    import generator

    data = scene(
        [
            generator.fan([0, 0, 0], 2.0, 8000, "red"),
            {"type": "sphere", "material": "m", "center": [0.3, 0.5, 0], "radius": 0.4},
        ],
        [{"type": "point", "color": 1, "position": [1, 3, 1]}],
        {"position": [0.3, 2, 3], "look_at": [0, 0, 0]},
        width=12,
        height=9,
    )
    agrees_with_brute_force(data)


def planet_and_speck(eye_height):
    return {
        "camera": {"position": [0, eye_height, 0], "look_at": [0, 3e-7, -2e-6], "fov": 60},
        "image": {"width": 24, "height": 18},
        "materials": {"ground": {"diffuse": [0.2, 0.6, 0.2]}, "red": {"diffuse": [0.9, 0.1, 0.1]}},
        "objects": [
            {"type": "sphere", "material": "ground", "center": [0, -1e9, 0], "radius": 1e9},
            {"type": "sphere", "material": "red", "center": [0, 3e-7, -2e-6], "radius": 3e-7},
        ],
        "lights": [{"type": "ambient", "color": 0.1}, {"type": "point", "color": 1, "position": [1e8, 1e8, 1e8]}],
    }


def test_a_planet_under_a_speck_just_before_an_eye_1e6_above_it():
    # the eye is 1e-6 above a sphere of radius 1e9 (float64 resolves 1.2e-7 there): it lies off the planet, so
    # the planet is seen and lit, and the speck of 3e-7 before the eye shows in its own colour
    img = render(planet_and_speck(1e-6))
    lit = 96  # the ground's green, lit, as an eye 10 times higher sees it below the horizon
    assert np.mean(render(planet_and_speck(1e-5))[12:, :, 1] == lit) > 0.9
    assert np.mean(img[12:, :, 1] == lit) > 0.9
    speck = (img[:, :, 0] > 2 * img[:, :, 1]) & (img[:, :, 0] > 20)
    assert 1 <= speck.sum() < 0.2 * speck.size
