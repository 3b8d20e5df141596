"""Plain triangles (tracer/proofs/sightlines.py): which go to Embree as themselves, and that nothing changes when they
do.

Every scene here is rendered twice: as the renderer does it (plain triangles
where the scene's rays allow) and with every triangle behind a closed proxy.
The images must be the same bytes, and the hits and shadows must agree with
the float64 brute force of test_exactness.
"""

import math
from unittest import mock

import numpy as np
import pytest
from test_exactness import agrees_with_brute_force, scene

import schemas
from tracer import Renderer, render
from tracer.proofs.planner import scene_sightlines
from tracer.proofs.sightlines import Sightlines, plain_triangles
from tracer.scene.camera import CameraRays
from tracer.scene.shapes import triangle_t
from tracer.scene.world import build_world


def sphere_mesh(center, radius, level=3, material="m"):
    """A closed mesh of ``8·4^level`` faces on a sphere (a subdivided octahedron), shared corners."""
    verts = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]
    faces = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]

    def middle(index, a, b):
        key = (min(a, b), max(a, b))
        if key not in index:
            index[key] = len(verts)
            verts.append([(verts[a][k] + verts[b][k]) / 2 for k in range(3)])
        return index[key]

    for _ in range(level):
        index, out = {}, []
        for a, b, c in faces:
            ab, bc, ca = middle(index, a, b), middle(index, b, c), middle(index, c, a)
            out += [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
        faces = out
    v = np.array(verts, float)
    v = np.asarray(center) + radius * v / np.linalg.norm(v, axis=1, keepdims=True)
    return {"type": "mesh", "material": material, "vertices": v.tolist(), "faces": faces}


def open_floor(size, n=6, y=0.0):
    xs = np.linspace(-size, size, n + 1)
    verts = [[float(x), y, float(z)] for z in xs for x in xs]
    faces = [[j * (n + 1) + i, (j + 1) * (n + 1) + i + 1, j * (n + 1) + i + 1] for j in range(n) for i in range(n)]
    faces += [[j * (n + 1) + i, (j + 1) * (n + 1) + i, (j + 1) * (n + 1) + i + 1] for j in range(n) for i in range(n)]
    return {"type": "mesh", "material": "m", "vertices": verts, "faces": faces}


def silhouette_edge(mesh, point):
    """The midpoint of an edge of ``mesh`` whose two faces lie on one side of the plane through it and ``point``
    (seen from there, the mesh folds away at that edge): the nearest such edge to the mesh's first vertex."""
    v, point = np.array(mesh["vertices"], float), np.asarray(point, float)
    edges = {}
    for f in mesh["faces"]:
        for k in range(3):
            a, b = sorted((f[k], f[(k + 1) % 3]))
            edges.setdefault((a, b), []).append(f[(k + 2) % 3])
    best = None
    for (a, b), opposite in edges.items():
        if len(opposite) != 2:
            continue
        plane = np.cross(v[a] - point, v[b] - point)
        s1, s2 = plane @ (v[opposite[0]] - point), plane @ (v[opposite[1]] - point)
        if s1 * s2 > 0:
            mid = (v[a] + v[b]) / 2
            if best is None or np.linalg.norm(mid - v[0]) < np.linalg.norm(best - v[0]):
                best = mid
    return best


def border_edge(mesh):
    """The midpoint of an edge of ``mesh`` that only one face has (the first found)."""
    v, faces = np.array(mesh["vertices"], float), mesh["faces"]
    count = {}
    for f in faces:
        for k in range(3):
            key = tuple(sorted((f[k], f[(k + 1) % 3])))
            count[key] = count.get(key, 0) + 1
    a, b = next(key for key, c in count.items() if c == 1)
    return (v[a] + v[b]) / 2


def on_floor(light, point):
    """Where the line from ``light`` through ``point`` meets y = 0."""
    light, point = np.asarray(light, float), np.asarray(point, float)
    return light + (point - light) * (light[1] / (light[1] - point[1]))


BALL = sphere_mesh([0, 0.6, 0], 0.6)
FLOOR = open_floor(2.5)
ROUGH = open_floor(1.0, n=30) | {
    "vertices": [[x, 0.3 + 1e-8 * math.sin(7 * x + 3 * z), z] for x, _, z in open_floor(1.0, n=30)["vertices"]]
}
EYE_SIDE, LIGHT_TOP = [0.3, 0.7, 4], [0.4, 3, 0.2]
CASES = {
    "mesh ball and open floor, point light": scene(
        [BALL, open_floor(2.5)],
        [{"type": "point", "color": 1, "position": [2, 3, 2]}],
        {"position": [0, 1.5, 4], "look_at": [0, 0.5, 0], "fov": 40},
    ),
    "the ball's silhouette at a 1e-5 degree field of view": scene(
        [BALL, FLOOR],
        [{"type": "point", "color": 1, "position": [-3, 2, 1]}],
        {"position": EYE_SIDE, "look_at": silhouette_edge(BALL, EYE_SIDE).tolist(), "fov": 1e-5},
    ),
    "the floor's border at a 1e-5 degree field of view": scene(
        [BALL, FLOOR],
        [{"type": "point", "color": 1, "position": [-3, 2, 1]}],
        {"position": [0.1, 0.5, 4], "look_at": border_edge(FLOOR).tolist(), "fov": 1e-5},
    ),
    "the ball's shadow edge on the floor at a 1e-5 degree field of view": scene(
        [BALL, FLOOR],
        [{"type": "point", "color": 1, "position": LIGHT_TOP}],
        {"position": [0, 2, 3], "look_at": on_floor(LIGHT_TOP, silhouette_edge(BALL, LIGHT_TOP)).tolist(), "fov": 1e-5},
    ),
    "a finely cut, slightly rough floor seen from 2e-6 above it, 1.5 away": scene(
        [ROUGH, BALL | {"vertices": (np.array(BALL["vertices"]) * 0.3 + [0, -0.1, -0.5]).tolist()}],
        [{"type": "point", "color": 1, "position": [0.5, 1, 1]}],
        {"position": [0.01, 0.3 + 2e-6, 0.95], "look_at": [0.3, 0.3, -0.55], "fov": 1e-4},
    ),
    "light grazing the ball, eye far and off the origin": scene(
        [
            sphere_mesh([1e4, 0.6, -1e4], 0.6),
            open_floor(2.5, y=0) | {"vertices": [[x + 1e4, y, z - 1e4] for x, y, z in open_floor(2.5)["vertices"]]},
        ],
        [
            {"type": "point", "color": 1, "position": [1e4 + 3, 0.61, -1e4]},
            {"type": "directional", "color": 0.5, "direction": [1, -0.05, 0]},
        ],
        {"position": [1e4 + 1, 2, -1e4 + 4], "look_at": [1e4, 0.6, -1e4], "fov": 35},
    ),
    "orthographic camera, area light, two touching balls": scene(
        [BALL, sphere_mesh([1.2, 0.6, 0], 0.6, level=2)],
        [
            {
                "type": "area",
                "color": 1,
                "corner": [-1, 3, -1],
                "edge_u": [2, 0, 0],
                "edge_v": [0, 0, 2],
                "samples": [2, 2],
            }
        ],
        {"type": "orthographic", "position": [0.6, 0.6, 5], "look_at": [0.6, 0.6, 0], "height": 1.5},
    ),
}


def without_plain(data):
    """Render with every triangle behind its proxy."""
    with mock.patch("tracer.stages.scene_sightlines", return_value=None):
        return render(schemas.validate_scene(data))


@pytest.mark.parametrize("name", sorted(CASES))
def test_plain_triangles_change_no_pixel(name):
    data = CASES[name]
    r = Renderer(schemas.validate_scene(data))
    p = r.intersector.walker.proxies
    faces_of = np.bincount(p.owner, minlength=len(p.lo))[: r.intersector.walker.n_tri]
    assert p.slack > 0 and np.sum(faces_of == 1) > 0, "the scene should have plain triangles (one face each)"
    assert np.sum(faces_of > 1) > 0, "and proxied ones"
    assert np.array_equal(r.pixels(), without_plain(data))


@pytest.mark.parametrize("name", sorted(CASES))
def test_plain_triangles_agree_with_the_brute_force(name):
    agrees_with_brute_force(CASES[name])


def lines_of(s, origin):
    return scene_sightlines(s, origin, CameraRays(s.camera, s.image, origin))


def classify(objects, lights, camera, **image):
    s = schemas.validate_scene(scene(objects, lights, camera, **image))
    w = build_world(s)
    lines = lines_of(s, w.origin)
    if lines is None:
        return None
    t = w.triangles
    return plain_triangles(t.v0, t.e1, t.e2, t.normal, t.corner_ids, lines, 4.0)[0]


EYE = {"position": [0, 0.6, 5], "look_at": [0, 0.6, 0], "fov": 40}


def test_a_closed_mesh_is_plain_away_from_its_silhouette():
    plain = classify([BALL], [{"type": "point", "color": 1, "position": [0, 0.6, 5]}], EYE)
    w = build_world(schemas.validate_scene(scene([BALL], [], EYE)))
    t = w.triangles
    centre = t.v0 + (t.e1 + t.e2) / 3 + w.origin
    facing = (centre - [0, 0.6, 0]) @ np.array([0, 0, 1.0]) / 0.6  # cosine towards the eye
    assert plain[np.abs(facing) > 0.3].all()  # well inside the front or the back
    assert not plain[np.abs(facing) < 0.02].any()  # seen edge-on


def test_borders_lone_triangles_and_mirrors_keep_their_proxies():
    tri = {"type": "triangle", "material": "m", "vertices": [[-1, -1, 0], [1, -1, 0], [0, 1, 0]]}
    floor = open_floor(1.0, n=4)
    plain = classify([tri, floor], [], {"position": [0, 3, 3], "look_at": [0, 0, 0]})
    assert not plain[0]  # a lone triangle: all its edges are borders
    n = 4
    faces = floor["faces"]
    border = [
        k
        for k, f in enumerate(faces)
        if sum(
            1 for a, b in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0])) if sum(1 for g in faces if a in g and b in g) == 1
        )
    ]
    assert not plain[1 + np.array(border)].any()
    assert plain[1:].sum() == 2 * n * n - len(border)
    cam = {"position": [0, 3, 3], "look_at": [0, 0, 0]}
    unused = schemas.validate_scene(scene([floor], [], cam))  # its materials include an unused mirror and glass
    assert lines_of(unused, np.zeros(3)) is not None
    assert lines_of(schemas.validate_scene(scene([floor | {"material": "mirror"}], [], cam)), np.zeros(3)) is None
    flat = schemas.validate_scene(scene([floor | {"material": "mirror"}], [], cam, max_depth=0))
    assert lines_of(flat, np.zeros(3)) is not None  # no secondary rays at all


def test_a_light_in_a_face_plane_or_beside_an_edge_makes_it_a_proxy():
    floor = open_floor(1.0, n=4)
    # a point light in the floor's plane sees every face edge-on
    plain = classify([floor], [{"type": "point", "color": 1, "position": [3, 0, 0]}], EYE | {"position": [0, 3, 3]})
    assert not plain.any()
    # a directional light along the floor: the same
    plain = classify(
        [floor], [{"type": "directional", "color": 1, "direction": [1, 0, 0.2]}], EYE | {"position": [0, 3, 3]}
    )
    assert not plain.any()


def test_sightlines_of_a_scene():
    s = schemas.validate_scene(
        scene(
            [BALL],
            [
                {"type": "ambient", "color": 0.1},
                {"type": "directional", "color": 1, "direction": [0, -2, 0]},
                {
                    "type": "area",
                    "color": 1,
                    "corner": [0, 2, 0],
                    "edge_u": [1, 0, 0],
                    "edge_v": [0, 0, 1],
                    "samples": [2, 2],
                },
            ],
            EYE,
        )
    )
    lines = lines_of(s, np.array([0, 1.0, 0]))
    assert isinstance(lines, Sightlines)
    assert len(lines.hulls) == 2 and lines.hulls[1].shape == (4, 3)  # the eye; the area light's corners
    assert np.allclose(lines.hulls[1][0], [0, 1, 0])  # local: minus the origin
    assert np.allclose(lines.directions[0], [0, -1, 0])


def test_a_ray_from_a_plain_face_to_a_light_or_the_eye_never_meets_its_mates():
    """The walk leaves out a plain face's mates (the faces across its edges) from a shadow ray's first tests,
    and from a camera ray's tests where it hits the face well inside: checked here on a bumpy terrain, whose
    valleys hide faces from the lights, against every mate."""
    rng = np.random.default_rng(11)
    n = 16
    terrain = open_floor(1.0, n=n)
    terrain["vertices"] = [[x, float(rng.uniform(0, 0.15)), z] for x, _, z in terrain["vertices"]]
    lights = [
        {"type": "point", "color": 1, "position": [1.5, 0.9, 0.2]},
        {
            "type": "area",
            "color": 1,
            "corner": [-0.5, 1.2, -0.4],
            "edge_u": [0.6, 0, 0],
            "edge_v": [0, 0.1, 0.5],
            "samples": [3, 3],
        },
    ]
    cam = {"position": [0, 2.5, 2.5], "look_at": [0, 0, 0]}
    s = schemas.validate_scene(scene([terrain], lights, cam))
    w = build_world(s)
    t = w.triangles
    plain, mates = plain_triangles(t.v0, t.e1, t.e2, t.normal, t.corner_ids, lines_of(s, w.origin), 4.0)
    assert 0.2 < plain.mean() < 0.8 and np.all(mates[~plain] == -1)
    f, k = np.nonzero(mates >= 0)
    both = plain[mates[f, k]]  # a plain face's mate, when plain, names it back
    assert both.any() and np.all(np.any(mates[mates[f, k][both]] == f[both, None], axis=1))
    # points of the plain faces (edges and corners too) towards every light point, against every mate
    targets = [np.asarray(lights[0]["position"], float)]
    corner, eu, ev = (np.asarray(lights[1][key], float) for key in ("corner", "edge_u", "edge_v"))
    targets += [corner + a * eu + b * ev for a in (0, 1 / 6, 0.5, 1) for b in (0, 0.5, 5 / 6, 1)]
    uv = np.vstack([rng.uniform(0, 1, (6, 2)), [[0, 0], [1, 0], [0, 1], [0.5, 0], [0, 0.5], [0.5, 0.5]]])
    uv[uv.sum(axis=1) > 1] = 1 - uv[uv.sum(axis=1) > 1][:, ::-1]
    met_others = []
    for light in targets:
        end = light - w.origin
        for a, b in uv:
            p = t.v0[f] + a * t.e1[f] + b * t.e2[f]
            d = end - p
            reach = np.linalg.norm(d, axis=1)
            d /= reach[:, None]
            g = mates[f, k]
            mag = np.abs(p).max(axis=1) + np.abs(w.origin).max()
            hit, _, _ = triangle_t(
                p,
                d,
                t.v0[g],
                t.e1[g],
                t.e2[g],
                t.normal[g],
                mag,
                t.mag[g],
                ends=end[None],
                mag_end=np.abs(light).max() + np.zeros(len(g)),
                uv=False,
            )
            assert not np.any(hit < reach)
            if len(met_others) < len(uv):  # other faces of the terrain do stand in the way of some of these rays
                rays, faces = np.meshgrid(np.arange(len(f)), np.arange(len(t.v0)), indexing="ij")
                rays, faces = rays.ravel(), faces.ravel()
                hit, _, _ = triangle_t(
                    p[rays],
                    d[rays],
                    t.v0[faces],
                    t.e1[faces],
                    t.e2[faces],
                    t.normal[faces],
                    mag[rays],
                    t.mag[faces],
                    faces == f[rays],
                    end[None],
                    np.abs(light).max() + np.zeros(len(rays)),
                    uv=False,
                )
                met_others.append(int(np.count_nonzero(hit < reach[rays])))
    assert sum(met_others) > 0
    # and a camera ray through a point well inside a plain face meets no mate anywhere along its line
    eye = np.asarray(cam["position"], float) - w.origin
    for a, b in uv[(uv.min(axis=1) > 0) & (uv.sum(axis=1) < 1)]:
        d = t.v0[f] + a * t.e1[f] + b * t.e2[f] - eye
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        g = mates[f, k]
        hit, _, _ = triangle_t(
            eye + 0 * d, d, t.v0[g], t.e1[g], t.e2[g], t.normal[g], np.abs(eye).max() + 1.0, t.mag[g], uv=False
        )
        assert not np.any(np.isfinite(hit))


def helicoid(turns=2, n=48, rings=6, pitch=0.15):
    """A ramp winding ``turns`` times about the y axis: its sheets overlap seen from above, and each face's
    mates are only its neighbours along the ramp."""
    verts = []
    for i in range(n * turns + 1):
        a = 2 * math.pi * i / n
        radii = np.linspace(0.2, 1.2, rings + 1).tolist()
        verts += [[r * math.cos(a), 0.4 + pitch * i / n, r * math.sin(a)] for r in radii]
    w = rings + 1
    faces = []
    for i in range(n * turns):
        for j in range(rings):
            a, b, c, d = i * w + j, i * w + j + 1, (i + 1) * w + j, (i + 1) * w + j + 1
            faces += [[a, c, b], [b, c, d]]
    return {"type": "mesh", "material": "m", "vertices": verts, "faces": faces}


@pytest.mark.parametrize("camera", [[0.2, 3, 0.3], [2.5, 1.2, 2]])
def test_a_ramp_over_itself_and_a_terrain_under_its_copy_agree_with_the_brute_force(camera):
    rng = np.random.default_rng(3)
    bumpy = open_floor(1.2, n=16)
    bumpy["vertices"] = [[x, float(rng.uniform(0, 0.12)), z] for x, _, z in bumpy["vertices"]]
    copy = bumpy | {"vertices": [[x, y + 1e-6, z] for x, y, z in bumpy["vertices"]]}
    lights = [
        {"type": "point", "color": 1, "position": [0.3, 2.5, -0.2]},
        {"type": "point", "color": 1, "position": [-1.8, 0.9, 0.5]},
    ]
    cam = {"position": camera, "look_at": [0, 0.5, 0]}
    for objects in ([helicoid()], [bumpy, copy]):
        data = scene(objects, lights, cam, width=80, height=60)
        assert Renderer(schemas.validate_scene(data)).intersector.walker.mates is not None  # plain faces, mates skipped
        agrees_with_brute_force(data)


def test_a_variants_shadow_rays_past_their_light_get_no_sightlines():
    """The walk spares a shadow ray the faces it does not meet on its way to its light: a variant's ray that runs
    on past the light (shadow-past-light) may meet them beyond it, so its render has no sightlines."""
    from tracer.scene.variants import VARIANTS

    s = schemas.validate_scene(scene([BALL], [{"type": "point", "color": 1, "position": [0, 0.6, 5]}], EYE))
    origin = build_world(s).origin
    camera = CameraRays(s.camera, s.image, origin)
    assert scene_sightlines(s, origin, camera) is not None
    assert scene_sightlines(s, origin, camera, VARIANTS["shadow-past-light"][0]) is None


def test_an_orthographic_camera_whose_up_is_used_as_given_gets_no_sightlines():
    """The orthographic camera's rays start on the plane through the eye across the view, which the sightlines'
    starts take as given; a variant whose camera keeps ``up`` as given (not perpendicular to the view) starts
    them off that plane, so it gets none, and the reference keeps them."""
    from tracer.scene.variants import VARIANTS

    s = schemas.validate_scene(
        {
            "camera": {"type": "orthographic", "position": [6, 5, 6], "look_at": [0, 0.5, 0], "height": 4},
            "image": {"width": 8, "height": 6},
            "materials": {"m": {}},
            "objects": [{"type": "triangle", "material": "m", "vertices": [[-1, 0, -1], [1, 0, -1], [0, 1, 1]]}],
            "lights": [{"type": "point", "color": 1, "position": [0, 4, 0]}],
        }
    )
    origin = np.zeros(3)
    assert scene_sightlines(s, origin, CameraRays(s.camera, s.image, origin)) is not None
    variant = VARIANTS["camera-up-as-given"][0]
    assert scene_sightlines(s, origin, CameraRays(s.camera, s.image, origin), variant) is None
