"""Words for a student: a diagnosis's objects, lights, terms and numbers as a person reads them.

A message names an object or a light by its ``name`` in quotes, else by its place ("the third light (area)",
:mod:`schemas.names`), and a coefficient in plain words ("missing", "twice as bright", "half as bright").  The
JSON of a diagnosis keeps the indices and the numbers; these words are for its sentences only.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from schemas.names import light_words, object_words

from ..images.figures import percent

#: a term fitted below this is missing, not just too weak (the diagnosis's own threshold)
MISSING = 0.05
#: plain words for a ratio near a simple fraction or multiple: (ratio, words); a ratio within
#: :data:`NEAR` (relative) of one is said in its words, any other as "about N times as bright"
RATIOS = (
    (0.25, "a quarter as bright"),
    (1 / 3, "a third as bright"),
    (0.5, "half as bright"),
    (2 / 3, "two thirds as bright"),
    (0.75, "three quarters as bright"),
    (1.5, "half again as bright"),
    (2.0, "twice as bright"),
    (3.0, "three times as bright"),
    (4.0, "four times as bright"),
)
#: how near (relative) a ratio must be to one of :data:`RATIOS` to be said in its words
NEAR = 0.08


@dataclass(frozen=True)
class Names:
    """How a scene's objects and lights are spoken of, by index (:func:`names_of`)."""

    objects: tuple[str, ...]
    lights: tuple[str, ...]

    def light(self, index: int | None) -> str:
        """A light's words; ``lights[K]`` past the list (a scene's names not known)."""
        if index is None:
            return "every light"
        return self.lights[index] if 0 <= index < len(self.lights) else f"lights[{index}]"

    def object(self, index: int) -> str:
        """An object's words ("the background" for −1); ``objects[K]`` past the list."""
        if index < 0:
            return "the background"
        return self.objects[index] if index < len(self.objects) else f"objects[{index}]"


def names_of(scene: Any) -> Names:
    """The words of every object and light of a validated scene."""
    return Names(
        tuple(object_words(scene, k) for k in range(len(scene.objects))),
        tuple(light_words(scene, k) for k in range(len(scene.lights))),
    )


def how_bright(scale: float) -> str:
    """A coefficient (1 is right) in words: "missing" below :data:`MISSING`, "twice as bright", "half as
    bright", "about 1.3 times as bright", "about 0.8 times as bright"."""
    if scale < MISSING:
        return "missing"
    for ratio, words in RATIOS:
        if abs(scale - ratio) <= NEAR * ratio:
            return words
    return f"about {scale:.1f} times as bright"


def term_name(name: str, light: int | None, names: Names) -> str:
    """ "the specular of light 'key'", "the ambient term", "the reflections"."""
    if light is not None:
        return f"the {name} of {names.light(light)}"
    return {"reflection": "the reflections", "refraction": "the refractions", "background": "the background"}.get(
        name, f"the {name} term"
    )


def term_sentence(name: str, light: int | None, scale: float, names: Names, joined: str = " ") -> str:
    """ "the specular of light 'key' is missing", "the diffuse of the second light (point) is twice as bright as
    the reference's"; with ``joined=", which "``, "the specular of light 'key', which is missing"."""
    how = how_bright(scale)
    tail = "" if how == "missing" else " as the reference's"
    verb = "are" if light is None and name in ("reflection", "refraction") else "is"
    return f"{term_name(name, light, names)}{joined}{verb} {how}{tail}"


#: the share of the difference that is "most of" it (:func:`share_words`)
MOST = 0.6


def share_words(share: float) -> str:
    """A share of the difference in words: "most of", "about half of", "some of", "a little of"."""
    if share >= MOST:
        return "most of"
    if share >= 0.35:
        return "about half of"
    if share >= 0.1:
        return "some of"
    return "a little of"


def objects_line(shares: list[tuple[int, float]], names: Names) -> str:
    """ "the first sphere 58 %, sphere 'ball' 20 %" for (object index, share) pairs."""
    return ", ".join(f"{names.object(k)} {round(100 * s)} %" for k, s in shares)


def lights_line(shares: list[tuple[int, float]], names: Names) -> str:
    """ "light 'key' 85 %, the third light (area) 40 %" for (light index, share) pairs."""
    return ", ".join(f"{names.light(k)} {round(100 * s)} %" for k, s in shares)


def together_sentence(
    mistakes: list[str], fraction: float, passes: bool, also: str = "", others: list[list[str]] | None = None
) -> str:
    """ "Likely two mistakes together: no shadow rays, and gamma 1/2.2 applied to the output — the submission
    matches the reference rendered with both (0.02 % of pixels off)"; ``also`` follows "both" (" and a ray
    offset of 0.003 along the normal").  With ``others``, the other readings of the same image: "…: no shadow rays
    and no refraction; or no shadow rays and the normal … — the image cannot tell them apart: the submission
    matches the reference rendered with either (…)"."""
    count = {2: "two", 3: "three"}.get(len(mistakes), str(len(mistakes)))
    how = "matches" if passes else "comes closest to"
    if others:
        every = "either" if len(others) == 1 else "any of them"
        said = "; or ".join(listed(m) for m in [mistakes, *others])
        return (
            f"Likely {count} mistakes together: {said} — the image cannot tell them apart: the submission {how} the "
            f"reference rendered with {every}{also} ({percent(fraction)} of pixels off)"
        )
    every = "both" if len(mistakes) == 2 else "all of them"
    return (
        f"Likely {count} mistakes together: {listed(mistakes)} — the submission {how} the reference rendered with "
        f"{every}{also} ({percent(fraction)} of pixels off)"
    )


#: what an image shows, in a student's words, where distinct mistakes give the same image: said of an image's
#: readings (:func:`readings_sentence`) when every one of them has the same words here
SHOWS = {
    "no-specular": "no specular highlight",
    "reflect-sign": "no specular highlight",
    "no-shadows": "no shadows",
    "transparent-no-shadows": "no shadows",
    "no-refraction": "glass that lets no light through",
    "exit-normal-not-flipped": "glass that lets no light through",
}


def listed(items: list[str], joined: str = "and") -> str:
    """ "a", "a and b", "a, b, and c" (``joined`` "or": "a, or b", "a, b, or c")."""
    if len(items) == 1:
        return items[0]
    if joined == "or":
        return ", ".join(items[:-1]) + ", or " + items[-1]
    return ", ".join(items[:-1]) + (", and " if len(items) > 2 else " and ") + items[-1]


def readings_sentence(variants: list[str], mistakes: list[str], fraction: float) -> str:
    """ "Likely: no specular term, or the reflected vector R with the wrong sign — the image cannot tell them apart
    (it shows no specular highlight): the submission matches the reference rendered with either (0.00 % of
    pixels off)", for the mistakes (``variants``, in words ``mistakes``) an image passes against each alone."""
    shows = {SHOWS.get(v) for v in variants}
    what = f" (it shows {shows.pop()})" if len(shows) == 1 and None not in shows else ""
    every = "either" if len(mistakes) == 2 else "any of them"
    return (
        f"Likely: {listed(mistakes, 'or')} — the image cannot tell them apart{what}: the submission matches the "
        f"reference rendered with {every} ({percent(fraction)} of pixels off)"
    )


def nearest_sentence(what: str, share: float) -> str:
    """ "No known mistake fits exactly: most of the difference is the specular of light 'key' (about 60 %)"."""
    return (
        f"No known mistake fits exactly: {share_words(share)} the difference is {what} (about {round(100 * share)} %)"
    )
