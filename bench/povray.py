"""The same scene for POV-Ray 3.7, for timing side by side.

Geometry, lights, resolution, recursion depth and the kind of shadows (hard,
or an area light of the same grid) are the same, so both renderers do the
same work; POV-Ray's finish model is not Phong-for-Phong, so the pictures are
close, not equal.  POV-Ray is left-handed: z is negated on the way in.
"""

from __future__ import annotations

import math
import shutil
from typing import Any

Scene = dict[str, Any]


def available() -> str | None:
    """Path of the ``povray`` executable, or None."""
    return shutil.which("povray")


def _v(p: Any) -> str:
    x, y, z = (float(c) for c in p)
    return f"<{x:.9g}, {y:.9g}, {-z:.9g}>"


def _c(c: Any) -> str:
    if isinstance(c, (int, float)):
        c = [c, c, c]
    return f"rgb <{float(c[0]):.6g}, {float(c[1]):.6g}, {float(c[2]):.6g}>"


def _grey(c: Any) -> float:
    return float(c) if isinstance(c, (int, float)) else sum(map(float, c)) / 3


def _texture(mat: dict[str, Any], materials: dict[str, Any], ambient_light: float) -> str:
    def plain(m: dict[str, Any]) -> tuple[str, str]:
        kd = m.get("diffuse", 0.5)
        kt = float(m.get("transmittance", 0))
        specular = _grey(m.get("specular", 0.8))
        roughness = 1 / max(float(m.get("shininess", 100)), 1)
        finish = (
            f"finish {{ ambient {_c(m.get('ambient', 0.3))} diffuse 1 specular {specular:.4g} "
            f"roughness {roughness:.4g} reflection {float(m.get('reflectance', 0)):.4g} }}"
        )
        pigment = f"color {_c(kd)} transmit {kt:.4g}" if kt else f"color {_c(kd)}"
        return pigment, finish

    pigment, finish = plain(mat)
    if "checker" in mat:
        other, _ = plain(materials[mat["checker"]["material"]])
        size = float(mat["checker"]["size"])
        pigment = f"checker {pigment.split(' transmit')[0]}, {other.split(' transmit')[0]} scale {size:.9g}"
    interior = f" interior {{ ior {float(mat.get('ior', 1.5)):.4g} }}" if float(mat.get("transmittance", 0)) else ""
    return f"texture {{ pigment {{ {pigment} }} {finish} }}{interior}"


def to_pov(scene: Scene) -> str:
    cam, img = scene["camera"], scene["image"]
    w, h = img["width"], img["height"]
    up = cam.get("up", [0, 1, 0])
    out = ["#version 3.7;"]
    ambient = [0.0, 0.0, 0.0]
    for light in scene.get("lights", []):
        if light["type"] == "ambient":
            c = light["color"]
            c = [c] * 3 if isinstance(c, (int, float)) else c
            ambient = [a + float(b) for a, b in zip(ambient, c)]
    out.append(
        f"global_settings {{ assumed_gamma 1.0 max_trace_level {img.get('max_depth', 4) + 1} "
        f"ambient_light {_c(ambient)} }}"
    )
    if cam.get("type") == "orthographic":
        half = cam.get("height", 2) / 2
        out.append(
            f"camera {{ orthographic location {_v(cam['position'])} sky {_v(up)} "
            f"right x*{2 * half * w / h:.9g} up y*{2 * half:.9g} look_at {_v(cam['look_at'])} }}"
        )
    else:
        hfov = 2 * math.degrees(math.atan(math.tan(math.radians(cam.get("fov", 60)) / 2) * w / h))
        out.append(
            f"camera {{ perspective location {_v(cam['position'])} sky {_v(up)} "
            f"right x*{w / h:.9g} up y angle {hfov:.9g} look_at {_v(cam['look_at'])} }}"
        )
    out.append(f"background {{ color {_c(img.get('background', 0))} }}")
    materials = scene.get("materials", {})
    for obj in scene.get("objects", []):
        tex = _texture(materials[obj["material"]], materials, sum(ambient) / 3)
        kind = obj["type"]
        if kind == "sphere":
            out.append(f"sphere {{ {_v(obj['center'])}, {float(obj['radius']):.9g} {tex} }}")
        elif kind == "plane":
            n = obj["normal"]
            norm = math.sqrt(sum(float(c) ** 2 for c in n))
            n = [float(c) / norm for c in n]
            d = sum(a * float(b) for a, b in zip(n, obj["point"]))
            out.append(f"plane {{ {_v(n)}, {d:.9g} {tex} }}")
        elif kind == "triangle":
            a, b, c = obj["vertices"]
            out.append(f"triangle {{ {_v(a)}, {_v(b)}, {_v(c)} {tex} }}")
        elif kind == "mesh":
            verts = ", ".join(_v(p) for p in obj["vertices"])
            faces = ", ".join(f"<{a}, {b}, {c}>" for a, b, c in obj["faces"])
            normals = ""
            if obj.get("normals"):
                normals = f"normal_vectors {{ {len(obj['normals'])}, {', '.join(_v(p) for p in obj['normals'])} }}"
            out.append(
                f"mesh2 {{ vertex_vectors {{ {len(obj['vertices'])}, {verts} }} {normals} "
                f"face_indices {{ {len(obj['faces'])}, {faces} }} {tex} }}"
            )
    for light in scene.get("lights", []):
        kind, colour = light["type"], _c(light["color"])
        if kind == "directional":
            d = [float(c) for c in light["direction"]]
            far = [-1e6 * c for c in d]
            out.append(f"light_source {{ {_v(far)} color {colour} parallel point_at <0, 0, 0> }}")
        elif kind == "point":
            out.append(f"light_source {{ {_v(light['position'])} color {colour} }}")
        elif kind == "spot":
            p = [float(a) + float(b) for a, b in zip(light["position"], light["direction"])]
            cutoff = light.get("cutoff", 45)
            inner = light.get("inner_cutoff", cutoff)
            out.append(
                f"light_source {{ {_v(light['position'])} color {colour} spotlight point_at {_v(p)} "
                f"radius {inner} falloff {cutoff} tightness 0 }}"
            )
        elif kind == "area":
            nu, nv = light.get("samples", [4, 4])
            eu, ev = light["edge_u"], light["edge_v"]
            centre = [float(c) + 0.5 * float(a) + 0.5 * float(b) for c, a, b in zip(light["corner"], eu, ev)]
            out.append(f"light_source {{ {_v(centre)} color {colour} area_light {_v(eu)}, {_v(ev)}, {nu}, {nv} }}")
    return "\n".join(out) + "\n"


def command(pov_file: str, png_file: str, width: int, height: int, threads: int = 2) -> list[str]:
    return [
        "povray",
        f"+I{pov_file}",
        f"+O{png_file}",
        f"+W{width}",
        f"+H{height}",
        f"+WT{threads}",
        "-D",
        "-V",
        "-GA",
        "+FN",
        "-A",
    ]
