"""Random scenes built to break a tracer's walk and numerics, from a seed.

:func:`scene` draws one family at random and gives a scene dict (valid by
the format); the same seed always gives the same scene.  The families aim at
what breaks walks and careless numerics:

* ``room``: a sphere or a mesh box around the camera, with balls and lights
  inside it;
* ``nested``: spheres in spheres: glass with an opaque core, onions of glass
  shells, a shell 10⁻⁶ thick, lights inside glass inside a room;
* ``overlap``: many overlapping spheres, cut by a mesh and a plane;
* ``lights``: lights at sphere centres, on spheres and planes, at mesh
  vertices and on mesh edges, an area light lying in a floor;
* ``cameras``: an eye on a plane, on a sphere or at its centre, and mirrors
  facing each other;
* ``scales``: a planet under tiny spheres near the eye, lights far away, thin
  shells;
* ``mesh``: terrains, icospheres (with and without vertex normals), fans of
  slivers and boxes, lit from points on them;
* ``dust``: specks 10⁻⁴ to 10⁻⁷ of the scene seen through a narrow field of
  view, where float32 cannot tell their outlines (the proxies' margins);
* ``thin``: a thin area light far away (edge over distance 10⁻⁴ to 10⁻¹⁰)
  over a floor, balls grazing the pyramid from the point in view to the
  light, seen through a view a few rounding errors of its faces wide;
* ``contact``: surfaces of different objects in one plane: glass, mirror and
  opaque boxes resting on a floor (a plane, a mesh or lone triangles), on one
  another and against a wall, tiles lying on the floor, the whole often
  turned so that its corners round; drawn for a tenth of the seeds, apart
  from the others, so that theirs stay the scenes they were.

Any scene may then be moved by up to 10⁶ and scaled by a power of ten
(attenuation scaled with it).  Coordinates are often on a grid of 1/8, so that
vertices, edge midpoints and planes meet lights and eyes exactly.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

Scene = dict[str, Any]
Rng = np.random.Generator


def _f(x: float) -> float:
    return float(x)


def _vec(a: Any) -> list[float]:
    return [float(v) for v in np.asarray(a, dtype=np.float64).reshape(3)]


def _triangle(rng: Rng) -> list[list[float]]:
    """Three grid points that make a triangle (the format refuses collinear vertices): drawn again until they do."""
    for _ in range(100):
        vertices = [_grid(rng, -2, 2) for _ in range(3)]
        a, b, c = (np.array(v) for v in vertices)
        if np.any(np.cross(b - a, c - a) != 0):
            return vertices
    raise AssertionError("no triangle in 100 draws")


def _grid(rng: Rng, lo: float, hi: float, step: float = 0.125) -> list[float]:
    """A point with coordinates on a grid of ``step`` (exact in binary)."""
    return [float(step * round(rng.uniform(lo, hi) / step)) for _ in range(3)]


def _unit(rng: Rng) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def _materials(rng: Rng) -> dict[str, Any]:
    def colour() -> list[float]:
        return [round(float(x), 3) for x in rng.uniform(0.1, 0.9, 3)]

    return {
        "matte": {"ambient": 0.2, "diffuse": colour(), "specular": 0.1, "shininess": 10.0},
        "shiny": {"ambient": 0.1, "diffuse": colour(), "specular": 0.7, "shininess": float(rng.choice([5, 40, 200]))},
        "mirror": {
            "ambient": 0.05,
            "diffuse": 0.1,
            "specular": 0.5,
            "reflectance": round(float(rng.uniform(0.5, 0.95)), 3),
        },
        "glass": {
            "ambient": 0.02,
            "diffuse": 0.05,
            "specular": 0.6,
            "transmittance": round(float(rng.uniform(0.6, 0.95)), 3),
            "reflectance": round(float(rng.uniform(0.0, 0.15)), 3),
            "ior": float(rng.choice([1.33, 1.5, 1.9, 0.8])),
        },
        "check": {"diffuse": colour(), "checker": {"size": float(rng.choice([0.25, 0.5, 1.0])), "material": "dark"}},
        "dark": {"ambient": 0.05, "diffuse": 0.15, "specular": 0.3},
    }


def _opaque(rng: Rng) -> str:
    return str(rng.choice(["matte", "shiny", "check", "matte", "shiny"]))


def _any(rng: Rng, mirrors: float = 0.3) -> str:
    r = rng.random()
    if r < mirrors / 2:
        return "mirror"
    if r < mirrors:
        return "glass"
    return _opaque(rng)


def sphere(c: Any, r: float, mat: str) -> dict[str, Any]:
    return {"type": "sphere", "material": mat, "center": _vec(c), "radius": _f(r)}


def plane(p: Any, n: Any, mat: str) -> dict[str, Any]:
    return {"type": "plane", "material": mat, "point": _vec(p), "normal": _vec(n)}


def box(lo: Any, hi: Any, mat: str) -> dict[str, Any]:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
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
    return {"type": "mesh", "material": mat, "vertices": [_vec(c) for c in corners], "faces": faces}


def icosphere(c: Any, r: float, mat: str, subdivisions: int, normals: bool) -> dict[str, Any]:
    phi = (1.0 + math.sqrt(5.0)) / 2.0
    v = [
        [-1, phi, 0],
        [1, phi, 0],
        [-1, -phi, 0],
        [1, -phi, 0],
        [0, -1, phi],
        [0, 1, phi],
        [0, -1, -phi],
        [0, 1, -phi],
        [phi, 0, -1],
        [phi, 0, 1],
        [-phi, 0, -1],
        [-phi, 0, 1],
    ]
    f = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ]
    verts = [np.asarray(p, float) / np.linalg.norm(p) for p in v]
    for _ in range(subdivisions):
        mids: dict[tuple[int, int], int] = {}

        def mid(a: int, b: int, mids: dict[tuple[int, int], int] = mids) -> int:
            key = (min(a, b), max(a, b))
            if key not in mids:
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                mids[key] = len(verts) - 1
            return mids[key]

        f = [
            g
            for a, b, cc in f
            for g in (
                [a, mid(a, b), mid(cc, a)],
                [b, mid(b, cc), mid(a, b)],
                [cc, mid(cc, a), mid(b, cc)],
                [mid(a, b), mid(b, cc), mid(cc, a)],
            )
        ]
    c = np.asarray(c, float)
    out = {"type": "mesh", "material": mat, "vertices": [_vec(c + r * p) for p in verts], "faces": f}
    if normals:
        out["normals"] = [_vec(p) for p in verts]
    return out


def terrain(rng: Rng, lo: float, hi: float, y: float, n: int, bump: float, mat: str) -> dict[str, Any]:
    xs = np.linspace(lo, hi, n + 1)
    verts = [[float(x), float(y + bump * 0.125 * round(rng.uniform(-1, 1) * 8)), float(z)] for z in xs for x in xs]
    faces = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            if rng.random() < 0.5:
                faces += [[a, a + n + 2, a + 1], [a, a + n + 1, a + n + 2]]
            else:
                faces += [[a, a + n + 1, a + 1], [a + 1, a + n + 1, a + n + 2]]
    return {"type": "mesh", "material": mat, "vertices": verts, "faces": faces}


def fan(c: Any, r: float, k: int, mat: str) -> dict[str, Any]:
    """``k`` slivers around the vertex ``c``, in the plane y = c.y."""
    c = np.asarray(c, float)
    verts = [_vec(c)] + [
        _vec(c + r * np.array([math.cos(a), 0.0, math.sin(a)])) for a in np.linspace(0, 2 * math.pi, k + 1)[:-1]
    ]
    faces = [[0, 1 + i, 1 + (i + 1) % k] for i in range(k)]
    return {"type": "mesh", "material": mat, "vertices": verts, "faces": faces}


def point(pos: Any, colour: float = 1.0, attenuation: list[float] | None = None) -> dict[str, Any]:
    out: dict[str, Any] = {"type": "point", "color": _f(colour), "position": _vec(pos)}
    if attenuation is not None:
        out["attenuation"] = attenuation
    return out


def _lights(rng: Rng, centre: Any, spread: float, count: int) -> list[dict[str, Any]]:
    centre = np.asarray(centre, float)
    out: list[dict[str, Any]] = [{"type": "ambient", "color": round(float(rng.uniform(0.05, 0.3)), 3)}]
    for _ in range(count):
        kind = rng.choice(["point", "point", "directional", "spot", "area"])
        pos = centre + rng.uniform(-spread, spread, 3)
        if kind == "point":
            att = None if rng.random() < 0.6 else [1.0, round(0.3 / spread, 4), round(0.1 / spread**2, 6)]
            out.append(point(pos, round(float(rng.uniform(0.4, 1.2)), 3), att))
        elif kind == "directional":
            out.append(
                {"type": "directional", "color": round(float(rng.uniform(0.2, 0.8)), 3), "direction": _vec(_unit(rng))}
            )
        elif kind == "spot":
            cutoff = float(rng.choice([20, 35, 50, 70]))
            inner = cutoff if rng.random() < 0.4 else cutoff * float(rng.uniform(0.3, 0.9))
            out.append(
                {
                    "type": "spot",
                    "color": 1.0,
                    "position": _vec(pos),
                    "direction": _vec(centre - pos + rng.normal(size=3) * 0.3 * spread),
                    "cutoff": cutoff,
                    "inner_cutoff": inner,
                    "exponent": float(rng.choice([0, 1, 4])),
                }
            )
        else:
            eu, ev = _unit(rng) * spread * 0.3, _unit(rng) * spread * 0.3
            if np.linalg.norm(np.cross(eu, ev)) < 0.1 * spread**2 * 0.09:
                ev = np.cross(eu, _unit(rng))
            out.append(
                {
                    "type": "area",
                    "color": 1.0,
                    "corner": _vec(pos),
                    "edge_u": _vec(eu),
                    "edge_v": _vec(ev),
                    "samples": [int(rng.integers(1, 4)), int(rng.integers(1, 3))],
                }
            )
    return out


def _camera(rng: Rng, eye: Any, target: Any, orthographic: float = 0.15, height: float = 4.0) -> dict[str, Any]:
    cam: dict[str, Any] = {"position": _vec(eye), "look_at": _vec(target)}
    if rng.random() < orthographic:
        cam["type"] = "orthographic"
        cam["height"] = _f(height)
    else:
        cam["fov"] = float(rng.choice([30, 50, 70, 100]))
    if rng.random() < 0.2:
        up = _unit(rng)
        f = np.asarray(target, float) - np.asarray(eye, float)
        if np.linalg.norm(np.cross(up, f)) > 0.1 * np.linalg.norm(f):
            cam["up"] = _vec(up)
    return cam


# -- families ---------------------------------------------------------------------------------------------------


def room(rng: Rng) -> tuple[dict[str, Any], list, list]:
    radius = float(rng.uniform(3, 10))
    eye = rng.uniform(-0.3, 0.3, 3) * radius
    objects: list[dict[str, Any]] = []
    if rng.random() < 0.6:
        objects.append(sphere(rng.uniform(-0.1, 0.1, 3) * radius, radius, _any(rng, 0.2)))
    else:
        objects.append(box(-radius * np.ones(3), radius * rng.uniform(0.6, 1.0, 3), _any(rng, 0.2)))
    for _ in range(int(rng.integers(2, 7))):
        objects.append(sphere(rng.uniform(-0.5, 0.5, 3) * radius, float(rng.uniform(0.1, 0.3)) * radius, _any(rng)))
    if rng.random() < 0.4:
        objects.append(plane([0, -0.5 * radius, 0], [0, 1, 0], _opaque(rng)))
    lights = _lights(rng, [0, 0, 0], 0.6 * radius, int(rng.integers(1, 4)))
    if rng.random() < 0.3:  # a light at a ball's centre
        lights.append(point(objects[-1]["center"] if objects[-1]["type"] == "sphere" else objects[1]["center"], 0.8))
    target = eye + _unit(rng) * radius
    return _camera(rng, eye, target, height=radius), objects, lights


def nested(rng: Rng) -> tuple[dict[str, Any], list, list]:
    objects: list[dict[str, Any]] = []
    c = rng.uniform(-1, 1, 3)
    r = float(rng.uniform(1, 2))
    kind = rng.choice(["core", "onion", "thin", "light"])
    if kind == "core":
        objects.append(sphere(c, r, "glass"))
        objects.append(sphere(c + rng.uniform(-0.2, 0.2, 3) * r, float(rng.uniform(0.2, 0.7)) * r, _opaque(rng)))
    elif kind == "onion":
        k = int(rng.integers(2, 7))
        for i in range(k):
            objects.append(sphere(c, r * (1.0 - i / k), str(rng.choice(["glass", "glass", "mirror", "matte"]))))
    elif kind == "thin":
        thickness = 10.0 ** -float(rng.uniform(2, 6))
        objects.append(sphere(c, r, "glass"))
        objects.append(sphere(c, r * (1.0 - thickness), "glass"))
        objects.append(sphere(c, 0.3 * r, _opaque(rng)))
    else:
        objects.append(sphere(c, r, "glass"))
        objects.append(sphere(c + np.array([0.0, 0.5 * r, 0.0]), 0.2 * r, _opaque(rng)))
    lights = _lights(rng, c, 3 * r, int(rng.integers(1, 3)))
    if rng.random() < 0.5:
        lights.append(point(c + rng.uniform(-0.3, 0.3, 3) * r, 1.0))  # inside the glass
    if rng.random() < 0.5:  # all of it inside a room
        objects.append(sphere(c, 8 * r, _opaque(rng)))
    if rng.random() < 0.5:
        objects.append(plane(c - [0, 1.5 * r, 0], [0, 1, 0], _opaque(rng)))
    if rng.random() < 0.25:  # the eye inside
        eye = c + rng.uniform(-0.3, 0.3, 3) * r
    else:
        eye = c + _unit(rng) * r * float(rng.uniform(2.5, 5))
    return _camera(rng, eye, c, height=3 * r), objects, lights


def overlap(rng: Rng) -> tuple[dict[str, Any], list, list]:
    objects = [
        sphere(rng.uniform(-1.5, 1.5, 3), float(rng.uniform(0.3, 1.3)), _any(rng))
        for _ in range(int(rng.integers(5, 16)))
    ]
    if rng.random() < 0.6:
        objects.append(box(rng.uniform(-1.5, 0, 3), rng.uniform(0, 1.5, 3), _any(rng, 0.15)))
    if rng.random() < 0.4:
        objects.append(
            icosphere(
                rng.uniform(-1, 1, 3),
                float(rng.uniform(0.5, 1.5)),
                _opaque(rng),
                int(rng.integers(0, 2)),
                rng.random() < 0.5,
            )
        )
    if rng.random() < 0.6:
        objects.append(plane(rng.uniform(-0.5, 0.5, 3), _unit(rng), _any(rng, 0.2)))
    eye = _unit(rng) * float(rng.uniform(4, 8))
    return _camera(rng, eye, [0, 0, 0], height=5.0), objects, _lights(rng, [0, 0, 0], 4.0, int(rng.integers(1, 4)))


def lights_on(rng: Rng) -> tuple[dict[str, Any], list, list]:
    floor_y = 0.0
    objects: list[dict[str, Any]] = [plane([0, floor_y, 0], [0, 1, 0], _opaque(rng))]
    balls = [
        sphere(_grid(rng, -1.5, 1.5) + np.array([0, 1.0, 0]), float(rng.choice([0.5, 0.75, 1.0])), _any(rng, 0.2))
        for _ in range(int(rng.integers(1, 4)))
    ]
    objects += balls
    mesh = (
        box(_grid(rng, -2, -0.5), _grid(rng, 0.5, 2), _opaque(rng))
        if rng.random() < 0.5
        else terrain(rng, -2.0, 2.0, 0.5, 3, 1.0, _opaque(rng))
    )
    objects.append(mesh)
    lights: list[dict[str, Any]] = [{"type": "ambient", "color": 0.1}]
    verts = np.asarray(mesh["vertices"])
    faces = np.asarray(mesh["faces"])
    for _ in range(int(rng.integers(1, 4))):
        where = rng.choice(["centre", "on_sphere", "vertex", "edge", "floor", "area_floor", "free"])
        b = balls[int(rng.integers(len(balls)))]
        if where == "centre":
            lights.append(point(b["center"], 1.0))
        elif where == "on_sphere":
            lights.append(point(np.asarray(b["center"]) + b["radius"] * _unit(rng), 1.0))
        elif where == "vertex":
            lights.append(point(verts[int(rng.integers(len(verts)))], 1.0))
        elif where == "edge":
            f = faces[int(rng.integers(len(faces)))]
            lights.append(point((verts[f[0]] + verts[f[1]]) / 2.0, 1.0))
        elif where == "floor":
            lights.append(point(_grid(rng, -2, 2) * np.array([1, 0, 1]) + [0, floor_y, 0], 1.0))
        elif where == "area_floor":
            lights.append(
                {
                    "type": "area",
                    "color": 1.5,
                    "corner": [-1.0, floor_y, 1.0],
                    "edge_u": [2.0, 0.0, 0.0],
                    "edge_v": [0.0, 0.0, 1.0],
                    "samples": [2, 2],
                }
            )
        else:
            lights.append(point(rng.uniform(-3, 3, 3) + [0, 3, 0], 1.0))
    if rng.random() < 0.3:
        lights.append({"type": "directional", "color": 0.5, "direction": [1.0, 0.0, 0.0]})  # in the floor's plane
    eye = np.array([0.0, 2.5, 5.0]) + rng.uniform(-1, 1, 3)
    return _camera(rng, eye, [0, 0.5, 0], height=6.0), objects, lights


def cameras(rng: Rng) -> tuple[dict[str, Any], list, list]:
    objects: list[dict[str, Any]] = [plane([0, 0, 0], [0, 1, 0], _opaque(rng))]
    ball = sphere([0.0, 1.0, -2.0], 1.0, _any(rng, 0.3))
    objects.append(ball)
    objects.append(sphere(rng.uniform(-2, 2, 3) + [0, 1, 0], 0.5, _any(rng)))
    kind = rng.choice(["on_plane", "centre", "on_sphere", "mirrors"])
    if kind == "on_plane":
        eye, target = [0.0, 0.0, 3.0], [0.0, float(rng.uniform(-0.5, 1.0)), -2.0]
    elif kind == "centre":
        eye, target = ball["center"], list(rng.uniform(-3, 3, 3))
    elif kind == "on_sphere":
        eye = list(np.asarray(ball["center"]) + _unit(rng))
        target = list(np.asarray(eye) + _unit(rng) * 3)
    else:
        gap = float(rng.uniform(2, 4))
        objects.append(plane([0, 0, -gap], [0, 0, 1], "mirror"))
        objects.append(plane([0, 0, gap], [0, 0.05 * float(rng.uniform(-1, 1)), -1], "mirror"))
        eye, target = [0.3, 1.0, 0.5 * gap], [0.0, 0.8, -gap]
    lights = _lights(rng, [0, 2, 0], 3.0, int(rng.integers(1, 3)))
    return _camera(rng, eye, target, orthographic=0.1), objects, lights


def scales(rng: Rng) -> tuple[dict[str, Any], list, list]:
    planet = 10.0 ** float(rng.uniform(2, 9))
    tiny = planet * 10.0 ** -float(rng.uniform(3, 9))  # (beyond 10⁻¹⁰ of the planet, float64 cannot tell)
    objects: list[dict[str, Any]] = [sphere([0.0, -planet, 0.0], planet, _opaque(rng))]
    for _ in range(int(rng.integers(1, 4))):
        r = tiny * float(rng.uniform(0.5, 2))
        objects.append(
            sphere(
                [
                    float(rng.uniform(-3, 3)) * tiny,
                    r * float(rng.choice([1.0, 1.5, 3.0])),
                    -float(rng.uniform(2, 6)) * tiny,
                ],
                r,
                _any(rng, 0.2),
            )
        )
    if rng.random() < 0.4:
        objects.append(sphere([0.0, 2 * tiny, -4 * tiny], tiny, "glass"))
        objects.append(sphere([0.0, 2 * tiny, -4 * tiny], tiny * (1 - 1e-6), "glass"))
    far = tiny * 10.0 ** float(rng.uniform(3, 9))
    lights: list[dict[str, Any]] = [
        {"type": "ambient", "color": 0.1},
        point(_unit(rng) * far * np.array([1, 0, 1]) + [0, far, 0], 1.0),
    ]
    if rng.random() < 0.5:
        lights.append(point([tiny, 4 * tiny, 0.0], 0.7))
    eye = [0.0, tiny * float(rng.uniform(1, 3)), 0.0]
    cam = _camera(rng, eye, [0.0, 0.0, -4 * tiny], orthographic=0.0)
    return cam, objects, lights


def mesh(rng: Rng) -> tuple[dict[str, Any], list, list]:
    objects: list[dict[str, Any]] = [
        terrain(rng, -3, 3, 0.0, int(rng.integers(2, 6)), float(rng.uniform(0, 1)), _opaque(rng))
    ]
    kind = rng.choice(["ico", "fan", "box", "lone"])
    if kind == "ico":
        objects.append(icosphere([0, 1.2, 0], 1.0, _any(rng, 0.2), int(rng.integers(0, 2)), rng.random() < 0.5))
    elif kind == "fan":
        objects.append(fan([0.0, 0.75, 0.0], 1.5, int(rng.integers(8, 80)), _opaque(rng)))
    elif kind == "box":
        objects.append(box([-1, 0.25, -1], [1, 1.5, 0.5], _any(rng, 0.2)))
    else:
        for _ in range(int(rng.integers(1, 5))):
            objects.append({"type": "triangle", "material": _opaque(rng), "vertices": _triangle(rng)})
    if rng.random() < 0.5:
        objects.append(sphere([1.0, 0.8, 1.0], 0.6, _any(rng)))
    lights = _lights(rng, [0, 2, 0], 2.5, int(rng.integers(1, 3)))
    verts = objects[-1].get("vertices") or objects[0]["vertices"]
    if rng.random() < 0.5:
        lights.append(point(verts[int(rng.integers(len(verts)))], 1.0))
    eye = _unit(rng) * float(rng.uniform(4, 7)) * np.array([1, 0.3, 1]) + [0, 3, 0]
    return _camera(rng, eye, [0, 0.5, 0], height=6.0), objects, lights


def dust(rng: Rng) -> tuple[dict[str, Any], list, list]:
    """Specks far smaller than the scene, seen through a narrow field of view: float32 cannot tell where their
    outlines lie, so every speck a ray grazes tests the proxies' margins and the cells' reach."""
    objects: list[dict[str, Any]] = [
        sphere(rng.uniform(-1, 1, 3), float(rng.uniform(0.2, 0.5)), _opaque(rng)) for _ in range(2)
    ]
    size = 10.0 ** -float(rng.uniform(4, 7))
    centre = rng.uniform(-0.5, 0.5, 3)
    for _ in range(int(rng.integers(20, 50))):
        c = centre + rng.normal(size=3) * size * 4
        if rng.random() < 0.7:
            objects.append(sphere(c, size * float(rng.uniform(0.3, 1.5)), _opaque(rng)))
        else:
            objects.append(
                {
                    "type": "triangle",
                    "material": _opaque(rng),
                    "vertices": [_vec(c + rng.normal(size=3) * size) for _ in range(3)],
                }
            )
    eye = centre + _unit(rng) * float(rng.uniform(0.3, 2.0))  # far beyond the cells' reach round the specks
    cam = _camera(rng, eye, centre, height=size * 12)
    if "fov" in cam:
        cam["fov"] = float(np.degrees(2 * np.arctan(8 * size / np.linalg.norm(eye - centre))))
    lights = [
        {"type": "ambient", "color": 0.1},
        point(centre + _unit(rng) * size * 30, 1.0),
        {"type": "directional", "color": 0.6, "direction": _vec(_unit(rng))},
    ]
    return cam, objects, lights


def thin(rng: Rng) -> tuple[dict[str, Any], list, list]:
    """A thin area light far away (edge over distance 10⁻⁴ to 10⁻¹⁰) over a floor: a ball grazes the shadow ray
    from the point the camera looks at to an outer sample (or a corner), by a tiny depth, near the floor or
    anywhere up to the light; a tiny ball may lie on the floor.  The pyramids' faces from such points are long
    and nearly parallel, and the camera's view is a few of their errors wide, where a proof that lost their
    direction declares a point seen."""
    # where the old faces lost most: about 10⁻⁸, their error then above the margin and their sign still right
    ratio = 10.0 ** float(rng.uniform(-8.5, -7) if rng.random() < 0.5 else rng.uniform(-10, -4))
    far = 10.0 ** float(rng.uniform(0, 8))
    toward = _unit(rng)
    toward[1] = abs(toward[1]) + 0.3
    toward /= np.linalg.norm(toward)
    a = np.cross(toward, _unit(rng))
    a /= np.linalg.norm(a)
    b = np.cross(toward, a)
    e_u, e_v = a * ratio * far * float(rng.uniform(0.3, 1)), (b + a * float(rng.uniform(-0.5, 0.5))) * ratio * far
    corner = toward * far - 0.5 * (e_u + e_v)
    corners = [corner, corner + e_u, corner + e_u + e_v, corner + e_v]
    samples = [int(rng.integers(1, 6)), int(rng.integers(1, 6))]
    objects: list[dict[str, Any]] = [plane([0, 0, 0], [0, 1, 0], _opaque(rng))]
    for _ in range(int(rng.integers(1, 3))):  # graze the shadow ray from the origin to a sample (or a corner)
        i, j = (int(rng.choice([0, n - 1])) if rng.random() < 0.7 else int(rng.integers(n)) for n in samples)
        end = (
            corner + (i + 0.5) / samples[0] * e_u + (j + 0.5) / samples[1] * e_v
            if rng.random() < 0.8
            else corners[int(rng.integers(4))]
        )
        at = float(rng.uniform(0.3, 0.98)) if rng.random() < 0.6 else 10.0 ** float(rng.uniform(-8, -0.05))
        on = end * at
        out = np.cross(end, np.cross(on - toward * (on @ toward), end))  # away from the pyramid's axis, across
        if np.linalg.norm(out) == 0:
            out = np.cross(end, _unit(rng))
        out /= np.linalg.norm(out)
        r = float(np.linalg.norm(on)) * 10.0 ** float(rng.uniform(-6, -1))
        depth = r * 10.0 ** float(rng.uniform(-8, -1)) * float(rng.choice([1, -1]))
        objects.append(sphere(on + out * (r - depth), r, _opaque(rng)))
    if rng.random() < 0.5:  # a tiny ball on the floor, as in a sun over a marble
        r = 10.0 ** float(rng.uniform(-3, 0))
        objects.append(sphere([float(rng.uniform(-2, 2)) * r, r * 1.2, float(rng.uniform(-2, 2)) * r], r, _opaque(rng)))
    pick = rng.random()  # a few faces' errors wide, a few edges wide, or the scene's own size
    view = (
        far * 10.0 ** float(rng.uniform(-9.5, -8))
        if pick < 0.5
        else far * ratio * 10.0 ** float(rng.uniform(-2, 2))
        if pick < 0.8
        else 10.0 ** float(rng.uniform(-2, 0))
    )
    eye = _unit(rng) * view * 3
    eye[1] = abs(eye[1]) + view
    lights = [
        {"type": "ambient", "color": 0.1},
        {
            "type": "area",
            "color": 1.0,
            "corner": _vec(corner),
            "edge_u": _vec(e_u),
            "edge_v": _vec(e_v),
            "samples": samples,
        },
    ]
    return _camera(rng, eye, [0.0, 0.0, 0.0], height=view * 2), objects, lights


def _floor(rng: Rng, size: float, mat: str) -> list[dict[str, Any]]:
    """A floor in the plane y = 0: a plane, a mesh of a few faces, or the same faces as lone triangles."""
    kind = rng.choice(["plane", "mesh", "lone"])
    if kind == "plane":
        return [plane([0, 0, 0], [0, 1, 0], mat)]
    n = int(rng.integers(1, 4))
    grid = terrain(rng, -size, size, 0.0, n, 0.0, mat)
    if kind == "mesh":
        return [grid]
    v = grid["vertices"]
    return [{"type": "triangle", "material": mat, "vertices": [v[i] for i in f]} for f in grid["faces"]]


def contact(rng: Rng) -> tuple[dict[str, Any], list, list]:
    objects = _floor(rng, 3.0, _opaque(rng))
    for _ in range(int(rng.integers(1, 4))):  # boxes resting on the floor, some on one another
        lo = np.array([_grid(rng, -2, 1)[0], 0.0, _grid(rng, -2, 1)[2]])
        hi = lo + [0.125 * int(rng.integers(4, 12)), 0.125 * int(rng.integers(2, 10)), 0.125 * int(rng.integers(4, 12))]
        objects.append(box(lo, hi, _any(rng, 0.6)))
        if rng.random() < 0.3:
            objects.append(
                box(lo + [0.25, 0, 0.25] * np.array([1, 0, 1]) + [0, hi[1] - lo[1], 0], hi + [0, 1, 0], _any(rng, 0.6))
            )
    for _ in range(int(rng.integers(0, 3))):  # tiles lying on the floor
        c = np.array(_grid(rng, -2, 2)) * [1, 0, 1]
        tile = [c + [-0.5, 0, -0.5], c + [0.5, 0, 0.75], c + [0.25, 0, -0.5]]
        objects.append({"type": "triangle", "material": _any(rng, 0.4), "vertices": [_vec(p) for p in tile]})
    if rng.random() < 0.4:  # a wall, and a box pushed against it
        objects.append(plane([0, 0, -2.5], [0, 0, 1], _opaque(rng)))
        objects.append(box([0.5, 0, -2.5], [1.5, 1, -1.75], _any(rng, 0.6)))
    order = rng.permutation(len(objects))
    objects = [objects[k] for k in order]
    lights = _lights(rng, [0, 3, 1], 2.0, int(rng.integers(1, 3)))
    eye = np.array([float(rng.uniform(-3, 3)), float(rng.uniform(1.5, 5)), float(rng.uniform(2.5, 5))])
    camera = _camera(rng, eye, [0, 0.3, 0], height=6.0)
    if rng.random() < 0.5:  # the whole turned: the planes stay planes, the corners round
        camera, objects, lights = _turned(rng, camera, objects, lights)
    return camera, objects, lights


def _turned(rng: Rng, camera: dict[str, Any], objects: list, lights: list) -> tuple[dict[str, Any], list, list]:
    q = np.linalg.qr(rng.normal(size=(3, 3)))[0]

    def pos(p: list[float]) -> list[float]:
        return _vec(q @ np.asarray(p, float))

    camera = {**camera, "position": pos(camera["position"]), "look_at": pos(camera["look_at"])}
    camera.pop("up", None)
    out = []
    for o in objects:
        o = dict(o)
        for key in ("center", "point", "normal"):
            if key in o:
                o[key] = pos(o[key])
        if "vertices" in o:
            o["vertices"] = [pos(v) for v in o["vertices"]]
        out.append(o)
    turned = []
    for light in lights:
        light = dict(light)
        for key in ("position", "corner", "edge_u", "edge_v", "direction"):
            if key in light:
                light[key] = pos(light[key])
        turned.append(light)
    return camera, out, turned


#: drawn for this share of the seeds, apart from the other families (:func:`scene`)
CONTACT_SHARE = 0.1

FAMILIES: dict[str, Callable[[Rng], tuple[dict[str, Any], list, list]]] = {
    "room": room,
    "nested": nested,
    "overlap": overlap,
    "lights": lights_on,
    "cameras": cameras,
    "scales": scales,
    "mesh": mesh,
    "dust": dust,
    "thin": thin,
    "contact": contact,
}


# -- moving and scaling -----------------------------------------------------------------------------------------


def transformed(data: Scene, shift: np.ndarray, factor: float) -> Scene:
    """The scene scaled by ``factor`` about the origin, then moved by ``shift`` (attenuation scaled with it)."""

    def pos(p: list[float]) -> list[float]:
        return [float(v) for v in np.asarray(p, float) * factor + shift]

    def vec(p: list[float]) -> list[float]:
        return [float(v) for v in np.asarray(p, float) * factor]

    out = {k: v for k, v in data.items()}
    cam = dict(data["camera"])
    cam["position"], cam["look_at"] = pos(cam["position"]), pos(cam["look_at"])
    if "height" in cam:
        cam["height"] = cam["height"] * factor
    out["camera"] = cam
    mats = {}
    for name, m in data["materials"].items():
        m = dict(m)
        if "checker" in m:
            m["checker"] = {**m["checker"], "size": m["checker"]["size"] * factor}
        mats[name] = m
    out["materials"] = mats
    objs = []
    for o in data["objects"]:
        o = dict(o)
        for key in ("center", "point"):
            if key in o:
                o[key] = pos(o[key])
        if "radius" in o:
            o["radius"] = o["radius"] * factor
        if "vertices" in o:
            o["vertices"] = [pos(v) for v in o["vertices"]]
        objs.append(o)
    out["objects"] = objs
    lights = []
    for light in data["lights"]:
        light = dict(light)
        for key in ("position", "corner"):
            if key in light:
                light[key] = pos(light[key])
        for key in ("edge_u", "edge_v"):
            if key in light:
                light[key] = vec(light[key])
        if "attenuation" in light:
            c, lin, q = light["attenuation"]
            light["attenuation"] = [c, lin / factor, q / factor**2]
        lights.append(light)
    out["lights"] = lights
    return out


def scene(seed: int, width: int = 20, height: int = 15, family: str | None = None) -> tuple[str, Scene]:
    """The generated scene of a seed: its family's name and the scene."""
    rng = np.random.default_rng(seed)
    if family is None:  # (the families before contact drawn as they were)
        family = str(rng.choice(sorted(set(FAMILIES) - {"contact"})))
        if np.random.default_rng([seed, 52]).random() < CONTACT_SHARE:
            family = "contact"
    name = family
    camera, objects, lights = FAMILIES[name](rng)
    image: dict[str, Any] = {
        "width": width,
        "height": height,
        "max_depth": int(rng.integers(0, 4)),
        "background": round(float(rng.uniform(0, 0.4)), 3),
    }
    if rng.random() < 0.1:
        image["samples"] = 2
    data: Scene = {"camera": camera, "image": image, "materials": _materials(rng), "objects": objects, "lights": lights}
    r = rng.random()
    if r < 0.35:
        shift = _unit(rng) * 10.0 ** float(rng.uniform(0, 6)) if rng.random() < 0.7 else np.zeros(3)
        factor = 10.0 ** float(rng.choice([0, 0, -3, 3, -8, 8, -20, 20])) if rng.random() < 0.5 else 1.0
        data = transformed(data, shift * factor, factor)
        name += "+moved"
    return name, data
