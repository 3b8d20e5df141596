"""Scenes built to break careless numerics, checked against a float64 brute force written here.

The brute force is deliberately naive and independent of the tracer: every
surface against every ray in world coordinates, the surface a ray leaves
excluded by identity, lights that lie on a surface not blocked by it.  For
each scene, the first surface of every primary ray and every shadow decision
from those hits must agree with the tracer, and the images must keep the
invariances the contract promises.
"""

import copy

import numpy as np
import pytest

import schemas
from helpers import differing, scaled, translated
from tracer import Renderer, encode_png
from tracer.intersect import MISS, PLANE, SPHERE, TRIANGLE

MATS = {"m": {"diffuse": 0.7}, "glass": {"transmittance": 0.9, "reflectance": 0.1, "ior": 1.5},
        "mirror": {"reflectance": 0.8}}


def scene(objects, lights, camera, width=64, height=48, **image):
    return {"camera": camera, "image": {"width": width, "height": height, **image}, "materials": MATS,
            "objects": objects, "lights": lights}


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
    faces = [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
             [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]
    return {"type": "mesh", "material": material, "vertices": corners, "faces": faces}


LOOK_DOWN = {"position": [0, 3, 3], "look_at": [0, 0, 0], "fov": 50}
HARD = {
    "point light a few thousandths above a floor, sliver above it": scene(
        [mesh_floor(4), {"type": "triangle", "material": "m",
                         "vertices": [[-1, 0.0005, 0.6], [1, 0.0005, 0.6], [0, 0.0005, 0.65]]}],
        [{"type": "point", "color": 1, "position": [0.1, 0.003, 1.0]}], LOOK_DOWN),
    "area light lying in a mesh floor": scene(
        [mesh_floor(4), {"type": "sphere", "material": "m", "center": [0, 0.5, 0], "radius": 0.5}],
        [{"type": "area", "color": 2, "corner": [-1, 0, 1], "edge_u": [2, 0, 0], "edge_v": [0, 0, 1],
          "samples": [3, 3]}], LOOK_DOWN),
    "lights in the plane of an orthographic camera's middle row": scene(
        [{"type": "plane", "material": "m", "point": [0, 0, 0], "normal": [0, 1, 0]},
         {"type": "sphere", "material": "m", "center": [0, 0, -2], "radius": 0.7}],
        [{"type": "point", "color": 1, "position": [2, 0, 0]}, {"type": "point", "color": 1, "position": [-2, 0, -4]}],
        {"type": "orthographic", "position": [0, 0, 5], "look_at": [0, 0, 0], "height": 3}, height=49),
    "glass and contact shadows with look_at a million units beyond": scene(
        [mesh_floor(3), {"type": "sphere", "material": "glass", "center": [0, 0.4, 0], "radius": 0.4},
         box([0.6, 0, -0.3], [0.9, 0.3, 0.0])],
        [{"type": "point", "color": 1, "position": [1, 3, 2]}],
        {"position": [0, 1.5, 3], "look_at": [0, 1.5 - 0.4 * 1e6, 3 - 1e6], "fov": 45}, max_depth=4),
    "triangle edges at a 1e-5 degree field of view": scene(
        [{"type": "triangle", "material": "m", "vertices": [[-1, -1, 0], [1, -1, 0], [0.3, 1, 0]]}],
        [{"type": "directional", "color": 1, "direction": [0, 0, -1]}],
        {"position": [0.65, 0, 10], "look_at": [0.65, 0, 0], "fov": 1e-5}),
    "tilted ground triangle reaching 1e5 away": scene(
        [{"type": "triangle", "material": "m", "vertices": [[-1e5, -1e5 * 0.05, 1e5], [1e5, 1e5 * 0.05, 1e5],
                                                            [0, 0, -1e5]]},
         {"type": "sphere", "material": "m", "center": [0, 0.3, 0], "radius": 0.3},
         {"type": "sphere", "material": "m", "center": [0.8, 0.2, 0.4], "radius": 0.15}],
        [{"type": "point", "color": 1, "position": [-3, 0.5, -1]}], LOOK_DOWN),
    "glass shell 1e-6 thick": scene(
        [{"type": "sphere", "material": "glass", "center": [0, 0, 0], "radius": 1.0},
         {"type": "sphere", "material": "glass", "center": [0, 0, 0], "radius": 1.0 + 1e-6},
         {"type": "plane", "material": "m", "point": [0, -1.2, 0], "normal": [0, 1, 0]}],
        [{"type": "point", "color": 1, "position": [2, 3, 2]}], {"position": [0, 0.5, 3.5], "look_at": [0, 0, 0]},
        max_depth=5),
    "column of 150 spheres along an orthographic camera's axis": scene(
        [{"type": "sphere", "material": "m", "center": [0.02 * (k % 3), 0, -0.1 * k], "radius": 0.06}
         for k in range(150)],
        [{"type": "directional", "color": 1, "direction": [0, -1, -1]}],
        {"type": "orthographic", "position": [0, 0, 5], "look_at": [0, 0, 0], "height": 0.3}),
    "light inside a sphere of radius 1e-5 and a closed box of 2e-5": scene(
        [{"type": "plane", "material": "m", "point": [0, 0, 0], "normal": [0, 1, 0]},
         {"type": "sphere", "material": "m", "center": [-1, 1, 0], "radius": 1e-5},
         box([1 - 1e-5, 1 - 1e-5, -1e-5], [1 + 1e-5, 1 + 1e-5, 1e-5])],
        [{"type": "point", "color": 1, "position": [-1, 1, 0]}, {"type": "point", "color": 1, "position": [1, 1, 0]}],
        LOOK_DOWN),
    "shade 4e-6 under a light": scene(
        [{"type": "plane", "material": "m", "point": [0, 0, 0], "normal": [0, 1, 0]},
         {"type": "triangle", "material": "m", "vertices": [[-0.01, 1 - 4e-6, -0.01], [0.01, 1 - 4e-6, -0.01],
                                                            [0, 1 - 4e-6, 0.01]]}],
        [{"type": "point", "color": 1, "position": [0, 1, 0]}], {"position": [0, 3, 0.5], "look_at": [0, 0, 0]}),
    "camera exactly on a floor and on a sphere": scene(
        [{"type": "plane", "material": "m", "point": [0, 0, 0], "normal": [0, 1, 0]},
         {"type": "sphere", "material": "m", "center": [0, 1, -3], "radius": 0.5}],
        [{"type": "point", "color": 1, "position": [0, 3, 0]}], {"position": [0, 0, 0], "look_at": [0, -0.2, -1]}),
    "camera on a sphere looking in": scene(
        [{"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 1}],
        [{"type": "point", "color": 1, "position": [0, 0.5, 0]}], {"position": [0, 0, 1], "look_at": [0, 0, 0]}),
}


# -- the brute force -------------------------------------------------------------
def surfaces(data):
    """Every surface of a scene in world coordinates: (kind, index within kind, parameters)."""
    out, counts = [], {SPHERE: 0, PLANE: 0, TRIANGLE: 0}
    for obj in data["objects"]:
        if obj["type"] == "sphere":
            out.append((SPHERE, counts[SPHERE], np.array(obj["center"], float), float(obj["radius"])))
            counts[SPHERE] += 1
        elif obj["type"] == "plane":
            n = np.array(obj["normal"], float)
            out.append((PLANE, counts[PLANE], np.array(obj["point"], float), n / np.linalg.norm(n)))
            counts[PLANE] += 1
        else:
            verts = np.array(obj["vertices"], float)
            for face in (obj.get("faces") or [[0, 1, 2]]):
                out.append((TRIANGLE, counts[TRIANGLE], verts[face[0]], verts[face[1]], verts[face[2]]))
                counts[TRIANGLE] += 1
    return out


def brute_t(surface, o, d, leaving, light=None):
    """Smallest t > 0 of one surface for rays o + t·d (world), ``inf`` for none."""
    kind = surface[0]
    if kind == SPHERE:
        c, r = surface[2], surface[3]
        oc = o - c
        b = np.sum(oc * d, axis=1)
        cc = np.sum(oc * oc, axis=1) - r * r
        disc = b * b - cc
        sq = np.sqrt(np.maximum(disc, 0))
        t1, t2 = -b - sq, -b + sq
        if light is not None:  # a light on the sphere: drop the root at the light
            on = abs(np.linalg.norm(light - c, axis=1) - r) < 1e-12 * (r + np.abs(c).max())
            dist = np.linalg.norm(light - o, axis=1)
            t1 = np.where(on & (abs(t1 - dist) < abs(t2 - dist)), np.inf, t1)
            t2 = np.where(on & (abs(t2 - dist) <= abs(t1 - dist)), np.inf, t2)
        t = np.where(t1 > 0, t1, np.where(t2 > 0, t2, np.inf))
        t = np.where(leaving, np.where(b < 0, -2 * b, np.inf), t)
        return np.where(disc >= 0, t, np.inf)
    if kind == PLANE:
        p, n = surface[2], surface[3]
        num, den = (p - o) @ n, d @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            t = num / den
        if light is not None:
            leaving = leaving | (abs((light - p) @ n) < 1e-12 * (1 + np.abs(p).max()))
        return np.where(~leaving & (t > 0) & np.isfinite(t), t, np.inf)
    v0, v1, v2 = surface[2:]
    e1, e2 = v1 - v0, v2 - v0
    n = np.cross(e1, e2)
    n = n / np.linalg.norm(n)
    pv = np.cross(d, e2)
    det = pv @ e1
    s = o - v0
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.sum(s * pv, axis=1) / det
        qv = np.cross(s, e1)
        v = np.sum(d * qv, axis=1) / det
        t = (qv @ e2) / det
    ok = (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0) & np.isfinite(t) & ~leaving
    if light is not None:
        ok &= ~(abs((light - v0) @ n) < 1e-12 * (1 + np.abs(np.stack([v0, v1, v2])).max()))
    return np.where(ok, t, np.inf)


def brute_closest(data, o, d, leave_kind, leave_index):
    best, kind, index = np.full(len(o), np.inf), np.zeros(len(o), np.int8), np.full(len(o), -1)
    for surface in surfaces(data):
        t = brute_t(surface, o, d, (leave_kind == surface[0]) & (leave_index == surface[1]))
        closer = t < best
        best[closer], kind[closer], index[closer] = t[closer], surface[0], surface[1]
    return best, kind, index


def brute_blocked(data, o, light, leave_kind, leave_index):
    v = light - o
    dist = np.linalg.norm(v, axis=1)
    d = v / dist[:, None]
    blocked = np.zeros(len(o), bool)
    for surface in surfaces(data):
        t = brute_t(surface, o, d, (leave_kind == surface[0]) & (leave_index == surface[1]), light)
        blocked |= t < dist
    return blocked


def point_lights(data):
    for light in data["lights"]:
        if light["type"] in ("point", "spot"):
            yield np.array(light["position"], float)
        elif light["type"] == "area":
            nu, nv = light["samples"]
            c, eu, ev = (np.array(light[k], float) for k in ("corner", "edge_u", "edge_v"))
            for i in range(nu):
                for j in range(nv):
                    yield c + (i + 0.5) / nu * eu + (j + 0.5) / nv * ev


@pytest.mark.parametrize("name", sorted(HARD))
def test_hits_and_shadows_agree_with_a_float64_brute_force(name):
    agrees_with_brute_force(HARD[name])


def agrees_with_brute_force(data):
    """Asserts that the first surface of every primary ray of ``data`` and every shadow decision from those
    hits agree with the brute force (within 0.1 % of the rays: exact ties may go either way)."""
    r = Renderer(schemas.validate_scene(data))
    n = data["image"]["width"] * data["image"]["height"]
    o, d = r.camera.rays(0, n)
    none_k, none_i = np.zeros(n, np.int8), np.full(n, -1)
    hits = r.intersector.closest(o, d, none_k, none_i)
    world_o = o + r.world.origin
    _, kind, index = brute_closest(data, world_o, d, none_k, none_i)
    agree = (hits.kind == kind) & (hits.index == index)
    assert np.mean(~agree) <= 0.001, f"{np.sum(~agree)} of {n} primary rays disagree"
    rows = np.flatnonzero(agree & (kind != MISS))
    point = hits.point[rows]
    world_point = point + r.world.origin
    checked = 0
    for light in point_lights(data):
        local = light - r.world.origin
        v = local - point
        dist = np.linalg.norm(v, axis=1)
        blocked = r.intersector.occluded(point, v / dist[:, None], dist, hits.kind[rows], hits.index[rows],
                                         np.broadcast_to(local, point.shape))
        expected = brute_blocked(data, world_point, np.broadcast_to(light, world_point.shape), kind[rows], index[rows])
        assert np.mean(blocked != expected) <= 0.001, f"{np.sum(blocked != expected)} shadow rays disagree"
        checked += len(rows)
    assert len(rows) > 0 and (checked > 0 or not list(point_lights(data)))


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


@pytest.mark.parametrize("name", ["glass and contact shadows with look_at a million units beyond",
                                  "tilted ground triangle reaching 1e5 away", "glass shell 1e-6 thick",
                                  "point light a few thousandths above a floor, sliver above it"])
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
