"""Diagnosis by experiment: a failing program asked the probes of its task, its answers put in sentences.

Each probe (:mod:`service.programs.probes`) is run by the student's program, in its sandbox and within its
limits, and rendered by phongray; the two are graded as the task is (its thresholds and accepted variants).
A probe the program renders right clears what it isolates; one it renders wrong points at it.

The probes are asked in stages, so that a part found wrong is not blamed on the next (:func:`experiment`):

1. the terms (``diffuse only``, ``specular only``, ``no glass``, ``no mirrors``).  Glass (or mirrors) is
   *missing* when the task's image is what the program renders of the task without it (its own answer to
   ``no glass``), or phongray's render of that; *wrong* when the scene without it is right and the one with
   it (without the other) is not;
2. what is missing or wrong of glass and mirrors is then taken out of the scene the later probes are made
   from, and the program's image of that scene (``no glass``, or ``without the glass and the mirrors``), when
   it is still wrong, is diagnosed as an uploaded image is: a classic mistake it shows there (``no shadow
   rays``) is a second mistake, found behind the first;
3. each light alone and the camera moved, from that scene, their references rendered with the classic
   mistakes already found (the task's own diagnosis's, and stage 2's): a light is told wrong only for what
   is wrong of it.  When no mistake is known and every light is wrong, one light's image alone (one without
   a spot's ramp first) is diagnosed: a mistake of every light (no shadow rays) shows there, and the
   answers are judged again with it.  For a spot's probe, the pixels it gets wrong against those of the
   spot's ramp between its inner and outer cone say whether the mistake is in that ramp alone.

A probe's answer is read as an uploaded image is (:func:`service.images.grading.read_submission`: a PNG of the
probe's size, checked on its header before anything is decompressed); one that cannot be read is that
probe's "no answer", as a run that failed is, and the experiment goes on; but a probe whose run timed out (or
used its CPU time) ends the experiment, as every later probe would take as long, and so does the student's
allowance of time for probes (:class:`Allowance`: all its tasks' experiments together) once spent.  The
sentences name what the probes show, never the scene's file or numbers, nor a run's exit status: a hidden
scene stays hidden.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field, fields, replace
from typing import TYPE_CHECKING

import numpy as np

from schemas import load_scene
from service.diagnosis.rendered import options_of
from tracer import decode_png, encode_png
from tracer.render import Renderer
from tracer.scene.variants import REFERENCE

from ..diagnosis.records import matched
from ..images.grading import ImageError, grade, read_submission
from ..work import pipeline
from .findings import sentences, unseen
from .outcome import Reason, RunOutcome
from .probes import LEFT_OUT, MAX_PROBES, Probe, Scene, aside_probe, camera_probe, light_probes, term_probes

if TYPE_CHECKING:
    from tracer.scene.variants import Options

#: the verdict of an answer that is not an image of the probe (not a PNG, the wrong size, a bomb)
UNREADABLE = "unreadable"


@dataclass(frozen=True)
class Thresholds:
    """How a probe is graded: the task's."""

    tolerance: float
    max_fraction: float
    accepted: dict[str, float] | None = None


@dataclass(frozen=True)
class Answer:
    """A probe and how the program answered it: ``right``, ``wrong``, ``unreadable`` or the reason its run
    failed; for a wrong spot's probe, whether every pixel it got wrong is in the spot's ramp (``in_ramp``);
    the program's pixels and phongray's reference, when it answered with an image."""

    probe: Probe
    verdict: str
    in_ramp: bool = False
    detail: str = ""
    pixels: np.ndarray | None = field(default=None, compare=False, repr=False)
    reference: np.ndarray | None = field(default=None, compare=False, repr=False)


@dataclass(frozen=True)
class Experiment:
    """The answers and the sentences they make, the first the likeliest mistake; the classic mistakes found
    behind the glass or mirrors (stage 2)."""

    answers: list[Answer]
    sentences: list[str] = field(default_factory=list)
    found: tuple[str, ...] = ()


def text(scene: Scene) -> bytes:
    return json.dumps(scene).encode()


def options(mistakes: tuple[str, ...]) -> Options:
    """The render options of the classic mistakes ``mistakes`` made together (``a+b`` ids split)."""
    merged = REFERENCE
    for name in (part for mistake in mistakes for part in mistake.split("+")):
        one = options_of(name)
        changed = {f.name: getattr(one, f.name) for f in fields(one)}
        merged = replace(merged, **{k: v for k, v in changed.items() if v != getattr(REFERENCE, k)})
    return merged


def render_png(scene: Scene, mistakes: tuple[str, ...] = ()) -> bytes:
    """phongray's render of a probe (the TA's scene, changed: trusted as the task's is), with ``mistakes``."""
    return encode_png(Renderer(load_scene(text(scene)), options(mistakes)).pixels(threads=1))


def read_answer(image: bytes, reference: np.ndarray) -> np.ndarray:
    """A program's image as an uploaded one is read (its size checked on the header first, against the
    probe's): :class:`service.images.grading.ImageError` when it is not one."""
    return read_submission(image, (reference.shape[1], reference.shape[0]))


def same(reference: np.ndarray, pixels: np.ndarray, limits: Thresholds) -> bool:
    """``pixels`` pass against ``reference`` under the task's thresholds (the reference alone)."""
    return grade(reference, pixels, "", limits.tolerance, limits.max_fraction).passed


def matches(reference_png: bytes, pixels: np.ndarray, probe: Probe, limits: Thresholds) -> bool:
    """The program's pixels pass against the probe's reference as the task's image would: with its accepted
    variants, for a probe whose reference is phongray's own (one rendered with mistakes is graded alone: the
    accepted variants are renders of the reference)."""
    reference = decode_png(reference_png)
    graded = pipeline.compare(reference_png, pixels, limits.tolerance, limits.max_fraction, reference=reference)
    if graded.grade.passed or probe.mistakes:
        return graded.grade.passed
    checks = pipeline.Checks(limits.accepted, diagnose=False)
    scene = load_scene(text(probe.scene))
    return pipeline.explain(scene, graded, reference, pixels, checks, pipeline.Checking(threads=1)).grade.passed


def _in_ramp(reference: np.ndarray, pixels: np.ndarray, hard: np.ndarray, limits: Thresholds) -> bool:
    """Every pixel the image gets wrong (by more than the tolerance), but for the task's allowed fraction, is
    one where the spot's ramp shows (the probe's render and the hard-edged spot's differ) or beside one."""
    ref, img, edge = (a.astype(np.int16) for a in (reference, pixels, hard))
    off = np.abs(img - ref).max(axis=2) > limits.tolerance
    ramp = np.abs(edge - ref).max(axis=2) > 0
    near = ramp.copy()
    for axis in (0, 1):
        for step in (-1, 1):
            near |= np.roll(ramp, step, axis=axis)
    return bool(off.any()) and int((off & ~near).sum()) <= limits.max_fraction * off.size


def ask(probe: Probe, run: Callable[[bytes], RunOutcome], limits: Thresholds) -> Answer:
    """The program's answer to one probe."""
    outcome = run(text(probe.scene))
    if not outcome.ok or outcome.image is None:
        return Answer(probe, str(outcome.reason), detail=outcome.detail)
    reference = decode_png(render_png(probe.scene, probe.mistakes))
    try:
        pixels = read_answer(outcome.image, reference)
    except ImageError as exc:
        return Answer(probe, UNREADABLE, detail=str(exc), reference=reference)
    return judge(probe, pixels, limits)


def judge(probe: Probe, pixels: np.ndarray, limits: Thresholds) -> Answer:
    """The program's image of a probe, right or wrong against phongray's render of it (with the probe's
    mistakes): so an answer is judged again, with no run, once a mistake is found behind it."""
    png = render_png(probe.scene, probe.mistakes)
    reference = decode_png(png)
    if matches(png, pixels, probe, limits):
        return Answer(probe, "right", pixels=pixels, reference=reference)
    in_ramp = False
    if probe.region is not None:
        in_ramp = _in_ramp(reference, pixels, decode_png(render_png(probe.region, probe.mistakes)), limits)
    return Answer(probe, "wrong", in_ramp, pixels=pixels, reference=reference)


@dataclass
class Allowance:
    """The seconds a student's probes may still take, all its tasks' experiments together."""

    seconds: float


#: a probe's run that ended so stops the experiment: every later probe would wait as long
STOPS = (Reason.TIMEOUT, Reason.CPU_TIME)


def charged(outcome: RunOutcome) -> float:
    """What a probe's run costs the student's allowance: its wall time less the time its processes waited,
    ready, for a CPU (a busy grading machine's, not the program's), never less than its CPU time; so that how
    busy the machine was does not decide how many probes a program is asked (a sleeping program waits for no
    CPU and is charged its whole wall time)."""
    return max(outcome.cpu_seconds, outcome.wall_seconds - outcome.waited_seconds)


class _Asking:
    """The probes asked of one program, at most :data:`MAX_PROBES` runs in all; none after one that timed out,
    nor once the student's ``allowance`` is spent."""

    def __init__(self, run: Callable[[bytes], RunOutcome], limits: Thresholds, allowance: Allowance | None = None):
        self.limits, self.answers = limits, []  # type: ignore[var-annotated]
        self.allowance, self.stopped, self.plain = allowance, False, run

    def run(self, scene: bytes) -> RunOutcome:
        outcome = self.plain(scene)
        if self.allowance is not None:
            self.allowance.seconds -= charged(outcome)
        self.stopped = outcome.reason in STOPS or (self.allowance is not None and self.allowance.seconds <= 0)
        return outcome

    def left(self) -> int:
        stopped = self.stopped or (self.allowance is not None and self.allowance.seconds <= 0)
        return 0 if stopped else MAX_PROBES - len(self.answers)

    def rejudge(self, mistakes: tuple[str, ...]) -> None:
        """Judge every answer so far again with ``mistakes`` (found since they were asked) in its reference."""
        self.answers = [
            a if a.pixels is None else judge(replace(a.probe, mistakes=mistakes), a.pixels, self.limits)
            for a in self.answers
        ]

    def all(self, probes: list[Probe], keep: int = 0) -> list[Answer]:
        """Ask ``probes`` in order, as many as leave ``keep`` runs for what follows (none once stopped)."""
        asked = []
        for probe in probes:
            if self.left() - keep <= 0:
                break
            asked.append(ask(probe, self.run, self.limits))
            self.answers.append(asked[-1])
        return asked


@dataclass(frozen=True)
class _Task:
    """The task's image (None: the run made none), phongray's reference of it (without any mistake), and
    whether the mistakes already known explain the image whole (it matches the reference made with them, or
    the reference itself when none is known)."""

    image: np.ndarray | None
    reference: np.ndarray
    explained: bool = False


def _state(term: str, by_name: dict[str, Answer], task: _Task, limits: Thresholds) -> str | None:
    """Of glass (``transmittance``) or mirrors (``reflectance``), where the scene has them: ``missing``,
    ``right``, ``wrong`` or None (the probes cannot tell)."""
    without = by_name.get("no glass" if term == "transmittance" else "no mirrors")
    kept = by_name.get("no mirrors" if term == "transmittance" else "no glass")
    if without is None:
        return None
    if _missing(without, task, limits):
        return "missing"
    if kept is not None and kept.verdict == "right":
        return "right"
    return "wrong" if without.verdict == "right" and not task.explained else None


def _missing(without: Answer, task: _Task, limits: Thresholds) -> bool:
    """The task's image is the scene without the term: phongray's render of it, or the program's own image of
    it; and the term shows (phongray's renders of the scene with and without it differ, without any mistake:
    a mistake the task's diagnosis read into the image may be another reading of this very one)."""
    if task.image is None or without.reference is None:
        return False
    plain = without.reference if not without.probe.mistakes else decode_png(render_png(without.probe.scene))
    if same(task.reference, plain, limits):
        return False
    own = without.pixels is not None and same(without.pixels, task.image, limits)
    return own or same(without.reference, task.image, limits)


def _diagnosed(answer: Answer, limits: Thresholds) -> tuple[str, ...]:
    """The classic mistakes a wrong answer shows, diagnosed as an uploaded image is (exact matches only)."""
    assert answer.pixels is not None and answer.reference is not None
    graded = pipeline.Graded(grade(answer.reference, answer.pixels, "", limits.tolerance, limits.max_fraction), None)
    scene = load_scene(text(answer.probe.scene))
    checks, run = pipeline.Checks(limits.accepted), pipeline.Checking(threads=1)
    found = pipeline.explain(scene, graded, answer.reference, answer.pixels, checks, run)
    if found.grade.passed or found.diagnosis is None:
        return ()
    return tuple(matched(found.diagnosis.as_dict())[:1])


Run = Callable[[bytes], RunOutcome]


def experiment(
    scene: bytes,
    image: bytes | None,
    run: Run,
    limits: Thresholds,
    known: tuple[str, ...] = (),
    allowance: Allowance | None = None,
) -> Experiment:
    """Ask a failing pair's program the probes of its task's ``scene`` (its text), ``image`` being what it
    rendered of the task (None when the run failed), ``known`` the classic mistakes the task's own diagnosis
    found (its exact matches), within the student's ``allowance`` of time, and say what the answers show (see
    the module's docstring for the stages)."""
    parsed = json.loads(scene)
    asking = _Asking(run, limits, allowance)
    terms = {a.probe.name: a for a in asking.all(term_probes(parsed, known), keep=1)}
    states = {}
    if "no glass" in terms or "no mirrors" in terms:
        task = _task(image, parsed, known, limits)
        states = {t: s for t in ("reflectance", "transmittance") if (s := _state(t, terms, task, limits)) is not None}
    aside = tuple(t for t in ("transmittance", "reflectance") if states.get(t) in ("missing", "wrong"))
    base, seen = parsed, ""
    behind: tuple[str, ...] = ()
    if aside:
        base = aside_probe(parsed, aside).scene
        behind = _behind(asking, _rest(asking, terms, aside, parsed, known), known)
        seen = f"{' and '.join(LEFT_OUT[t] for t in aside)} left out"
    lights = asking.all(light_probes(base, known + behind), keep=1)
    alone = _alone(lights) if not (known or behind) else None
    if alone is not None:  # (no mistake known yet, and the lights are wrong: what one of them shows alone)
        behind, seen = _behind(asking, alone, known), f"the {alone.probe.name}"
    asking.all([camera_probe(base, known + behind)])
    said = sentences(asking.answers, states, unseen(behind, seen))
    return Experiment(asking.answers, said, behind)


def _alone(lights: list[Answer]) -> Answer | None:
    """The light's answer to diagnose when every light is wrong: a classic mistake of them all (no shadow rays)
    shows in each; one without a spot's ramp first (a ramp may be a mistake of its own)."""
    wrong = [a for a in lights if a.verdict == "wrong"]
    if not wrong or len(wrong) < len(lights):
        return None
    return next((a for a in wrong if a.probe.region is None), wrong[0])


def _behind(asking: _Asking, answer: Answer | None, known: tuple[str, ...]) -> tuple[str, ...]:
    """The classic mistake a wrong answer shows (diagnosed), and every answer so far judged again with it."""
    if answer is None or answer.verdict != "wrong":
        return ()
    found = _diagnosed(answer, asking.limits)
    if found:
        asking.rejudge(known + found)
    return found


def _task(image: bytes | None, scene: Scene, known: tuple[str, ...], limits: Thresholds) -> _Task:
    """The task's image, read as its grade read it, its reference, and whether ``known`` explains it."""
    reference = decode_png(render_png(scene))
    try:
        pixels = None if image is None else read_answer(image, reference)
    except ImageError:
        return _Task(None, reference)
    with_known = decode_png(render_png(scene, known)) if known else reference
    return _Task(pixels, reference, pixels is not None and same(with_known, pixels, limits))


def _rest(
    asking: _Asking, terms: dict[str, Answer], aside: tuple[str, ...], scene: Scene, known: tuple[str, ...]
) -> Answer | None:
    """The program's image of the scene with ``aside`` taken out: its answer to ``no glass`` (or ``no
    mirrors``) when that is the one taken out, else one more probe (when a run is left for it besides the
    camera's)."""
    if aside == ("transmittance",):
        return terms.get("no glass")
    if aside == ("reflectance",):
        return terms.get("no mirrors")
    asked = asking.all([aside_probe(scene, aside, known)], keep=1)
    return asked[0] if asked else None
