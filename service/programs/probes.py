"""Probe scenes: the questions a failing program is asked, each a scene derived from its task's.

A probe changes one thing of the task's scene, so that the program's render of it, compared with phongray's
render of the same probe, says whether the program gets that one thing right:

* a term of the shading isolated through the materials: ``diffuse only`` (ambient, specular, mirror and glass
  weights zero), ``specular only``, ``no glass`` (transmittance zero: mirrors kept) and ``no mirrors``
  (reflectance zero: glass kept), each only where the scene has that term;
* each light alone (the scene's other lights, its ambient light included, taken out), where the scene has
  more than one, or the one is a spot with a ramp between its inner and outer cone (whose probe then also
  names that ramp's pixels: :attr:`Probe.region`);
* the camera moved (turned 20° about the vertical through the point it looks at; a camera straight above it
  is not moved): the program's image follows the camera, not only the task's picture.

A probe is a pure function of the scene's JSON: the same scene gives the same probes, in the same order (the
terms, then the lights in the scene's order, then the camera; :func:`probes`), at most :data:`MAX_PROBES` of
them, so that a failing pair costs at most that many runs of the student's program.  What a program is
already found to get wrong is kept out of the probes asked after (:mod:`.experiment`): the scene they are
made from has those terms taken out (:func:`zeroed`), and phongray renders their reference with the classic
mistakes found (:attr:`Probe.mistakes`), so that a light is not blamed for the glass or the shadows.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

#: the most probes a failing pair is asked (each one run of the student's program)
MAX_PROBES = 8
#: how far the camera is turned about the vertical through its look_at point, in degrees
TURN_DEGREES = 20.0

Scene = dict[str, Any]


class Kind(StrEnum):
    TERM = "term"
    LIGHT = "light"
    CAMERA = "camera"


@dataclass(frozen=True)
class Probe:
    """One question: its name in words (``light 'key' alone``), what it isolates (its kind and subject: the
    term's name, the light's index, ``camera``), the scene, and for a spot's probe, a second scene (the spot
    without its ramp: ``inner_cutoff`` = ``cutoff``) whose render differs from the probe's exactly on the
    ramp's pixels, the region a mistake can be located in; the classic mistakes (``tracer.scene.variants`` ids)
    the program is already found to make, which phongray renders the probe's reference with."""

    name: str
    kind: Kind
    subject: str
    scene: Scene
    region: Scene | None = None
    mistakes: tuple[str, ...] = ()


def _materials(scene: Scene) -> list[dict[str, Any]]:
    return list(scene.get("materials", {}).values())


def _value(material: dict[str, Any], key: str, default: float) -> float:
    """The largest channel of a material's number or colour (0 means the term is off)."""
    given = material.get(key, default)
    return max(given) if isinstance(given, list) else float(given)


#: the scene format's defaults of the terms a probe sets
DEFAULTS = {"ambient": 0.3, "diffuse": 0.5, "specular": 0.8, "reflectance": 0.0, "transmittance": 0.0}
#: each term probe: its name, the term it isolates, and the material keys it sets to zero
TERMS = (
    ("diffuse only", "diffuse", ("ambient", "specular", "reflectance", "transmittance")),
    ("specular only", "specular", ("ambient", "diffuse", "reflectance", "transmittance")),
    ("no glass", "transmittance", ("transmittance",)),
    ("no mirrors", "reflectance", ("reflectance",)),
)


def _has(scene: Scene, key: str) -> bool:
    return any(_value(m, key, DEFAULTS[key]) > 0 for m in _materials(scene))


def zeroed(scene: Scene, keys: tuple[str, ...]) -> Scene:
    """The scene with the material ``keys`` (terms: ``transmittance``, ``reflectance``, ...) set to zero."""
    out = copy.deepcopy(scene)
    for material in out.get("materials", {}).values():
        material.update({key: 0 for key in keys})
    return out


def term_probes(scene: Scene, mistakes: tuple[str, ...] = ()) -> list[Probe]:
    """The terms the scene has: ``diffuse only`` and ``specular only`` where a material has that term, ``no
    glass`` where one is glass (the mirrors then shown without it), ``no mirrors`` where one is a mirror."""
    return [
        Probe(name, Kind.TERM, term, zeroed(scene, keys), mistakes=mistakes)
        for name, term, keys in TERMS
        if _has(scene, term)
    ]


#: a term taken out of the scene, as a probe's name says it
LEFT_OUT = {"transmittance": "the glass", "reflectance": "the mirrors", "specular": "specular", "diffuse": "diffuse"}


def aside_probe(scene: Scene, keys: tuple[str, ...], mistakes: tuple[str, ...] = ()) -> Probe:
    """The task's scene with the terms ``keys`` taken out (those found wrong): what the program makes of the
    rest of it (``without the glass and the mirrors``)."""
    words = " and ".join(LEFT_OUT[key] for key in keys)
    return Probe(f"without {words}", Kind.TERM, "+".join(keys), zeroed(scene, keys), mistakes=mistakes)


def light_label(light: dict[str, Any], index: int) -> str:
    """A light as a sentence names it: its type and its name, or its place (``spot light 'key'``,
    ``point light lights[2]``)."""
    name = light.get("name")
    return f"{light['type']} light " + (f"'{name}'" if name else f"lights[{index}]")


def _ramp(light: dict[str, Any]) -> bool:
    """A spot whose intensity ramps between its inner and outer cone."""
    outer = light.get("cutoff", 45)
    return light["type"] == "spot" and light.get("inner_cutoff", outer) < outer


def light_probes(scene: Scene, mistakes: tuple[str, ...] = ()) -> list[Probe]:
    """Each light alone, where the scene has more than one or the one is a spot with a ramp (else none)."""
    lights = scene.get("lights", [])
    lit = [(n, light) for n, light in enumerate(lights) if light["type"] != "ambient"]
    if len(lit) < 2 and not any(_ramp(light) for _, light in lit):
        return []
    found = []
    for index, light in lit:
        alone = {**copy.deepcopy(scene), "lights": [copy.deepcopy(light)]}
        region = None
        if _ramp(light):
            region = {**copy.deepcopy(alone), "lights": [{**copy.deepcopy(light), "inner_cutoff": light["cutoff"]}]}
        found.append(Probe(f"{light_label(light, index)} alone", Kind.LIGHT, str(index), alone, region, mistakes))
    return found


def _turned(scene: Scene) -> Scene:
    """The camera turned :data:`TURN_DEGREES` about the vertical (world y) through its look_at point."""
    out = copy.deepcopy(scene)
    camera = out["camera"]
    eye, at = camera["position"], camera["look_at"]
    dx, dz = eye[0] - at[0], eye[2] - at[2]
    turn = math.radians(TURN_DEGREES)
    c, s = math.cos(turn), math.sin(turn)
    camera["position"] = [at[0] + c * dx + s * dz, eye[1], at[2] - s * dx + c * dz]
    return out


def camera_probe(scene: Scene, mistakes: tuple[str, ...] = ()) -> Probe:
    return Probe("the camera moved", Kind.CAMERA, "camera", _turned(scene), mistakes=mistakes)


def probes(scene: Scene) -> list[Probe]:
    """The probes of a task's scene (its parsed JSON) before anything is known of the program, at most
    :data:`MAX_PROBES`, in the module's order.  The camera's probe is kept when there are more: it is the one
    a program that only reproduces the task's picture fails."""
    found = term_probes(scene) + light_probes(scene)
    return [*found[: MAX_PROBES - 1], camera_probe(scene)]
