"""A student's ray tracer as a program: ``python3 tracer.py SCENE OUTPUT``, the standard library only.

It is what the class-grading tests hand in as a student's program (a sandboxed run sees the system's python3,
not this project's NumPy): spheres and planes; ambient, directional, point and spot lights; Phong shading with
shadows; mirror and glass rays, written from the scene format.  A file ``mistakes.txt`` beside it (one word a
line) switches a classic mistake on: ``no-shadows``, ``no-specular``, ``spot-hard-edge`` (the spot's cone
without its ramp between the inner and outer cutoff), ``no-refraction`` (glass ignored).  Shadow and secondary
rays start 1e-6 along the normal, an offset the grade accepts.
"""

import json
import math
import os
import struct
import sys
import zlib

OFFSET = 1e-6
HERE = os.path.dirname(os.path.abspath(__file__))
try:
    with open(os.path.join(HERE, "mistakes.txt")) as listed:
        WRONG = set(listed.read().split())
except OSError:
    WRONG = set()


def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def mul(a, k):
    return (a[0] * k, a[1] * k, a[2] * k)


def had(a, b):
    return (a[0] * b[0], a[1] * b[1], a[2] * b[2])


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def unit(a):
    return mul(a, 1.0 / math.sqrt(dot(a, a)))


def colour(value):
    return (float(value),) * 3 if isinstance(value, (int, float)) else tuple(float(v) for v in value)


def material(given):
    m = {
        "ambient": 0.3,
        "diffuse": 0.5,
        "specular": 0.8,
        "shininess": 100,
        "reflectance": 0,
        "transmittance": 0,
        "ior": 1.5,
        **given,
    }
    for key in ("ambient", "diffuse", "specular"):
        m[key] = colour(m[key])
    return m


def hit_sphere(obj, o, d):
    oc = sub(o, obj["center"])
    b = dot(oc, d)
    disc = b * b - (dot(oc, oc) - obj["radius"] ** 2)
    if disc < 0:
        return None
    root = math.sqrt(disc)
    for t in (-b - root, -b + root):
        if t > 1e-9:
            return t
    return None


def hit_plane(obj, o, d):
    n = unit(obj["normal"])
    dn = dot(d, n)
    if dn == 0:
        return None
    t = dot(sub(obj["point"], o), n) / dn
    return t if t > 1e-9 else None


def closest(scene, o, d):
    best = None
    for obj in scene["objects"]:
        t = (hit_sphere if obj["type"] == "sphere" else hit_plane)(obj, o, d)
        if t is not None and (best is None or t < best[0]):
            best = (t, obj)
    return best


def normal_at(obj, p):
    if obj["type"] == "sphere":
        return mul(sub(p, obj["center"]), 1.0 / obj["radius"])
    return unit(obj["normal"])


def towards(light, p):
    """The unit vector towards the light, its distance and its intensity at p."""
    if light["type"] == "directional":
        return mul(unit(light["direction"]), -1.0), math.inf, colour(light["color"])
    v = sub(light["position"], p)
    dist = math.sqrt(dot(v, v))
    c, lin, q = light.get("attenuation", (1, 0, 0))
    strength = 1.0 / (c + lin * dist + q * dist * dist)
    to = mul(v, 1.0 / dist)
    if light["type"] == "spot":
        s = dot(unit(light["direction"]), mul(to, -1.0))
        outer = math.cos(math.radians(light.get("cutoff", 45)))
        inner = math.cos(math.radians(light.get("inner_cutoff", light.get("cutoff", 45))))
        if s < outer:
            return to, dist, (0.0, 0.0, 0.0)
        ramp = 1.0 if s >= inner or "spot-hard-edge" in WRONG else (s - outer) / (inner - outer)
        strength *= s ** light.get("exponent", 1) * ramp
    return to, dist, mul(colour(light["color"]), strength)


def shade(scene, p, n, view, m):
    ambient = (0.0, 0.0, 0.0)
    for light in scene["lights"]:
        if light["type"] == "ambient":
            ambient = add(ambient, colour(light["color"]))
    result = had(m["ambient"], ambient)
    for light in scene["lights"]:
        if light["type"] == "ambient":
            continue
        to, dist, intensity = towards(light, p)
        nl = dot(n, to)
        if nl <= 0:
            continue
        if "no-shadows" not in WRONG:
            blocker = closest(scene, add(p, mul(n, OFFSET)), to)
            if blocker is not None and blocker[0] < dist:
                continue
        r = sub(mul(n, 2 * nl), to)
        rv = dot(r, view)
        spec = rv ** m["shininess"] if rv > 0 and "no-specular" not in WRONG else 0.0
        term = add(mul(m["diffuse"], nl), mul(m["specular"], spec))
        result = add(result, had(intensity, term))
    return result


def trace(scene, o, d, depth):
    found = closest(scene, o, d)
    if found is None:
        return colour(scene["image"].get("background", 0))
    t, obj = found
    p = add(o, mul(d, t))
    outward = normal_at(obj, p)
    n = mul(outward, -1.0) if dot(outward, d) > 0 else outward
    m = scene["materials"][obj["material"]]
    result = shade(scene, p, n, mul(d, -1.0), m)
    if depth >= scene["image"].get("max_depth", 4):
        return result
    if m["reflectance"] > 0:
        mirror = sub(d, mul(n, 2 * dot(d, n)))
        result = add(result, mul(trace(scene, add(p, mul(n, OFFSET)), mirror, depth + 1), m["reflectance"]))
    if m["transmittance"] > 0 and "no-refraction" not in WRONG:
        into = dot(d, outward) < 0
        eta, w = (1 / m["ior"], outward) if into else (m["ior"], mul(outward, -1.0))
        c = -dot(d, w)
        k = 1 - eta * eta * (1 - c * c)
        bent = sub(d, mul(w, 2 * dot(d, w))) if k < 0 else unit(add(mul(d, eta), mul(w, eta * c - math.sqrt(k))))
        start = add(p, mul(w, -OFFSET if k >= 0 else OFFSET))
        result = add(result, mul(trace(scene, start, bent, depth + 1), m["transmittance"]))
    return result


def render(scene):
    cam, img = scene["camera"], scene["image"]
    W, H = img["width"], img["height"]
    eye = tuple(cam["position"])
    f = unit(sub(cam["look_at"], eye))
    r = unit(cross(f, cam.get("up", (0, 1, 0))))
    u = cross(r, f)
    h = math.tan(math.radians(cam.get("fov", 60)) / 2)
    rows = []
    for j in range(H):
        row = bytearray(b"\0")
        for i in range(W):
            x = (2 * (i + 0.5) / W - 1) * W / H * h
            y = (1 - 2 * (j + 0.5) / H) * h
            c = trace(scene, eye, unit(add(f, add(mul(r, x), mul(u, y)))), 0)
            row += bytes(math.floor(255 * min(max(v, 0.0), 1.0) + 0.5) for v in c)
        rows.append(bytes(row))
    return W, H, b"".join(rows)


def write_png(path, width, height, data):
    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    with open(path, "wb") as out:
        out.write(
            b"\x89PNG\r\n\x1a\n"
            + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(data))
            + chunk(b"IEND", b"")
        )


def main():
    with open(sys.argv[1]) as given:
        scene = json.load(given)
    scene.setdefault("objects", [])
    scene.setdefault("lights", [])
    scene["materials"] = {name: material(m) for name, m in scene.get("materials", {}).items()}
    write_png(sys.argv[2], *render(scene))


if __name__ == "__main__":
    main()
