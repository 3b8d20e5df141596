"""Diagnosis by experiment: a failing program asked the probes of its task, its answers put in sentences.

Each probe (:mod:`service.programs.probes`) is run by the student's program, in its sandbox and within its
limits, and rendered by phongray; the two are graded as the task is (its thresholds and accepted variants).
A probe the program renders right clears what it isolates; one it renders wrong points at it.  Two more
comparisons cost no run: the student's image of the task itself against phongray's render of the task
without its glass (or mirrors) says the program leaves refraction (or reflection) out; and for a spot's
probe, the pixels it gets wrong against the pixels of the spot's ramp between its inner and outer cone
(where phongray's render of the probe and of the spot without its ramp differ, and their neighbours) say
whether the mistake is in that ramp alone.

The sentences name what the probes show, never the scene's file or numbers: a hidden scene stays hidden.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .outcome import RunOutcome
from .probes import Kind, Probe, Scene, light_label, probes


@dataclass(frozen=True)
class Thresholds:
    """How a probe is graded: the task's."""

    tolerance: float
    max_fraction: float
    accepted: dict[str, float] | None = None


@dataclass(frozen=True)
class Answer:
    """A probe and how the program answered it: ``right``, ``wrong``, or the reason its run failed; for a
    wrong spot's probe, whether every pixel it got wrong is in the spot's ramp (``in_ramp``)."""

    probe: Probe
    verdict: str
    in_ramp: bool = False
    detail: str = ""


@dataclass(frozen=True)
class Experiment:
    """The answers and the sentences they make, the first the likeliest mistake."""

    answers: list[Answer]
    sentences: list[str] = field(default_factory=list)


def text(scene: Scene) -> bytes:
    return json.dumps(scene).encode()


def render_png(scene: bytes) -> bytes:
    """phongray's render of a probe (the TA's scene, changed: trusted as the task's is)."""
    from schemas import load_scene
    from tracer import encode_png, render

    return encode_png(render(load_scene(scene), threads=1))


def matches(reference: bytes, image: bytes, scene: bytes, limits: Thresholds) -> bool:
    """The image passes against the reference as the task's image would (its accepted variants included)."""
    from schemas import load_scene

    from .. import grading, pipeline

    try:
        graded = pipeline.grade_png(
            reference,
            image,
            limits.tolerance,
            limits.max_fraction,
            explaining=pipeline.Explaining(
                lambda: load_scene(scene), pipeline.Checks(limits.accepted, diagnose=False), pipeline.Run(threads=1)
            ),
        )
    except grading.ImageError:
        return False
    return graded.grade.passed


def _in_ramp(reference: bytes, image: bytes, hard: bytes, limits: Thresholds) -> bool:
    """Every pixel the image gets wrong (by more than the tolerance), but for the task's allowed fraction, is
    one where the spot's ramp shows (the probe's render and the hard-edged spot's differ) or beside one."""
    from tracer import decode_png

    ref, img, edge = (decode_png(png).astype(np.int16) for png in (reference, image, hard))
    if img.shape != ref.shape:
        return False
    off = np.abs(img - ref).max(axis=2) > limits.tolerance
    ramp = np.abs(edge - ref).max(axis=2) > 0
    near = ramp.copy()
    for axis in (0, 1):
        for step in (-1, 1):
            near |= np.roll(ramp, step, axis=axis)
    return bool(off.any()) and int((off & ~near).sum()) <= limits.max_fraction * off.size


def ask(probe: Probe, run: Callable[[bytes], RunOutcome], limits: Thresholds) -> Answer:
    """The program's answer to one probe."""
    scene = text(probe.scene)
    outcome = run(scene)
    if not outcome.ok or outcome.image is None:
        return Answer(probe, str(outcome.reason), detail=outcome.detail)
    reference = render_png(scene)
    if matches(reference, outcome.image, scene, limits):
        return Answer(probe, "right")
    in_ramp = probe.region is not None and _in_ramp(reference, outcome.image, render_png(text(probe.region)), limits)
    return Answer(probe, "wrong", in_ramp)


def experiment(scene: bytes, image: bytes | None, run: Callable[[bytes], RunOutcome], limits: Thresholds) -> Experiment:
    """Ask a failing pair's program the probes of its task's ``scene`` (its text), ``image`` being what it
    rendered of the task (None when the run failed), and say what the answers show."""
    parsed = json.loads(scene)
    answers = [ask(probe, run, limits) for probe in probes(parsed)]
    left_out = set() if image is None else _left_out(answers, image, limits)
    return Experiment(answers, sentences(answers, left_out))


def _left_out(answers: list[Answer], image: bytes, limits: Thresholds) -> set[str]:
    """The terms (``reflectance``, ``transmittance``) the task's image is rendered without: it matches
    phongray's render of the task with that term taken out."""
    out = set()
    for answer in answers:
        probe = answer.probe
        if probe.kind is Kind.TERM and probe.name.startswith("no "):
            scene = text(probe.scene)
            if matches(render_png(scene), image, scene, limits):
                out.add(probe.subject)
    return out


#: a term taken out by a probe, in a sentence
TERM_WORDS = {"reflectance": "reflection", "transmittance": "refraction", "diffuse": "diffuse", "specular": "specular"}
#: the probe that takes out each of mirrors and glass: with the other one's probe, they say which is wrong
WITHOUT = {"reflectance": "no mirrors", "transmittance": "no glass"}


def _mirrors_and_glass(by_name: dict[str, Answer], left_out: set[str]) -> str | None:
    """``reflection right, refraction missing``: for mirrors and glass each, where the scene has them,
    ``missing`` (the task's image is phongray's without it), ``right`` (the probe without the other is right),
    ``wrong`` (the probe without it is right, the one without the other is not or does not exist)."""
    words = []
    for term, other in (("reflectance", "transmittance"), ("transmittance", "reflectance")):
        without, kept = by_name.get(WITHOUT[term]), by_name.get(WITHOUT[other])
        if without is None:
            continue
        if term in left_out:
            words.append(f"{TERM_WORDS[term]} missing")
        elif kept is not None and kept.verdict == "right":
            words.append(f"{TERM_WORDS[term]} right")
        elif without.verdict == "right":
            words.append(f"{TERM_WORDS[term]} wrong")
    return ", ".join(words) if words and any("right" not in w for w in words) else None


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


def sentences(answers: list[Answer], left_out: set[str]) -> list[str]:
    """What the answers show, the likeliest mistake first: a light, mirrors and glass, the shading's terms, a
    picture right only from the task's camera, then a probe the program could not render."""
    by_name = {a.probe.name: a for a in answers}
    said = _lights(answers)
    said += [s for s in (_mirrors_and_glass(by_name, left_out), _terms(by_name)) if s]
    camera = by_name.get("the camera moved")
    others = [a for a in answers if a is not camera]
    if camera is not None and camera.verdict == "wrong" and all(a.verdict == "right" for a in others):
        said.append("your program's image is wrong once the camera moves: it follows the task's picture, not the scene")
    failed = [a for a in answers if a.verdict not in ("right", "wrong")]
    if failed:
        said.append(f"on the probe '{failed[0].probe.name}' the program's run failed: {failed[0].detail}")
    return said
