"""What a program's answers to its probes show, in sentences a student reads (:mod:`.experiment` asks them).

The likeliest mistake comes first: glass or mirrors missing or wrong (the parts the later probes were made
without), a classic mistake found behind them (or in a light's image alone), a light wrong (between a spot's
inner and outer cone, where that is all that is wrong), diffuse or specular wrong, a picture right only from
the task's camera, and then a probe the program gave no answer to.  A light wrong while another is right
locates the mistake, and diffuse or specular is not blamed for it; every light wrong with a term wrong is the
term's mistake, and no light is blamed for it.  A sentence names a light by its ``name`` in the scene, or its place,
and says nothing else of the scene; a run that failed is told as it is told to a student
(:func:`.outcome.told`), never with its exit status.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from tracer.scene.variants import MORE_VARIANTS, VARIANTS

from .outcome import Reason, told
from .probes import Kind, light_label

if TYPE_CHECKING:
    from .experiment import Answer

#: a term taken out by a probe, in a sentence
TERM_WORDS = {"reflectance": "reflection", "transmittance": "refraction", "diffuse": "diffuse", "specular": "specular"}


def unseen(found: tuple[str, ...], seen: str) -> str | None:
    """``no shadow rays (seen with the glass left out)``: the classic mistakes found behind another, and the
    probe that showed them."""
    if not found:
        return None

    words = {name: said for name, (_, said) in {**VARIANTS, **MORE_VARIANTS}.items()}
    named = " and ".join(words.get(part, part) for mistake in found for part in mistake.split("+"))
    return f"{named} (seen with {seen})"


def _mirrors_and_glass(states: dict[str, str]) -> str | None:
    """``reflection right, refraction missing``: each of mirrors and glass the probes could tell, when one of
    them is not right."""
    words = [f"{TERM_WORDS[t]} {states[t]}" for t in ("reflectance", "transmittance") if t in states]
    return ", ".join(words) if any(not w.endswith("right") for w in words) else None


def _lights(answers: list[Answer]) -> list[str]:
    lights = [a for a in answers if a.probe.kind is Kind.LIGHT and a.verdict in ("right", "wrong")]
    wrong = [a for a in lights if a.verdict == "wrong"]
    said = []
    for answer in wrong:
        label = light_label(answer.probe.scene["lights"][0], int(answer.probe.subject))
        where = " between its inner and outer cone" if answer.in_ramp else ""
        said.append(f"your {label} is wrong{where}")
    if wrong and len(wrong) < len(lights):
        right = [light_label(a.probe.scene["lights"][0], int(a.probe.subject)) for a in lights if a not in wrong]
        said.append(f"alone, your {' and '.join(right)} {'is' if len(right) == 1 else 'are'} right")
    return said


def _terms(by_name: dict[str, Answer]) -> str | None:
    words = [
        f"{TERM_WORDS[by_name[name].probe.subject]} {by_name[name].verdict}"
        for name in ("diffuse only", "specular only")
        if name in by_name and by_name[name].verdict in ("right", "wrong")
    ]
    return ", ".join(words) if any(w.endswith("wrong") for w in words) else None


def _unanswered(answer: Answer) -> str:
    """A probe the program gave no image of it for: its run failed, or what it wrote is not an image of it."""
    if answer.verdict == "unreadable":
        return f"on the probe '{answer.probe.name}' the program's image could not be read (not a PNG of its size)"
    return f"on the probe '{answer.probe.name}' the program's run {told(Reason(answer.verdict))}"


def sentences(answers: list[Answer], states: dict[str, str], behind: str | None = None) -> list[str]:
    """What the answers show, the likeliest mistake first (see the module's docstring); ``states`` what the
    probes tell of mirrors and glass (``reflectance``/``transmittance`` → ``missing``, ``wrong``, ``right``),
    ``behind`` the sentence of a mistake found behind them."""
    by_name = {a.probe.name: a for a in answers}
    said = [s for s in (_mirrors_and_glass(states), behind) if s]
    lights = [a.verdict for a in answers if a.probe.kind is Kind.LIGHT and a.verdict in ("right", "wrong")]
    located = "wrong" in lights and "right" in lights  # (a light alone is wrong: not diffuse or specular)
    terms = None if located else _terms(by_name)
    if not (terms and lights and set(lights) == {"wrong"}):  # (every light wrong, and a term: the term)
        said += _lights(answers)
    said += [terms] if terms else []
    camera = by_name.get("the camera moved")
    others = [a for a in answers if a is not camera]
    if camera is not None and camera.verdict == "wrong" and all(a.verdict == "right" for a in others):
        said.append("your program's image is wrong once the camera moves: it follows the task's picture, not the scene")
    failed = [a for a in answers if a.verdict not in ("right", "wrong")]
    if failed:
        said.append(_unanswered(failed[0]))
    return said
