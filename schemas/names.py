"""How a message to a student speaks of an object or a light of a scene: by its ``name`` (phongray's extension of
the format, docs/scene-format.md), else by its place among its kind ("the first sphere", "the third light
(area)").  The JSON of a result keeps the index; these words are for sentences."""

from __future__ import annotations

from .scene import Scene

_ORDINALS = ("first", "second", "third", "fourth", "fifth", "sixth", "seventh", "eighth", "ninth", "tenth")


def ordinal(n: int) -> str:
    """``1`` → "first" … ``10`` → "tenth"; beyond, "11th", "21st", "22nd", "103rd" (n ≥ 1)."""
    if n < 1:
        raise ValueError(f"an ordinal counts from 1, not {n}")
    if n <= len(_ORDINALS):
        return _ORDINALS[n - 1]
    suffix = "th" if n % 100 in (11, 12, 13) else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{suffix}"


def object_words(scene: Scene, index: int) -> str:
    """``objects[index]`` for a student: "sphere 'ball'" when it has a name, else "the second sphere" (its
    place among the scene's objects of its type)."""
    obj = scene.objects[index]
    if obj.name is not None:
        return f"{obj.type} '{obj.name}'"
    place = sum(1 for other in scene.objects[: index + 1] if other.type == obj.type)
    return f"the {ordinal(place)} {obj.type}"


def light_words(scene: Scene, index: int) -> str:
    """``lights[index]`` for a student: "light 'key'" when it has a name, else "the third light (area)" (its
    place among all the scene's lights, and its type)."""
    light = scene.lights[index]
    if light.name is not None:
        return f"light '{light.name}'"
    return f"the {ordinal(index + 1)} light ({light.type})"
