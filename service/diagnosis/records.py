"""What a diagnosis says: its causes, the terms out of scale, the objects and lights where the failing pixels
are, and the words for it (a sentence for a person, a headline for a report's cell)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from typing import Any, Literal, TypeVar

from pydantic import Field
from pydantic.fields import FieldInfo

from tracer.scene.variants import SENTENCES

from ..images.figures import percent
from .words import MOST, Names, nearest_sentence, readings_sentence, term_sentence, together_sentence

#: the key of a record's field metadata that says how the service's answer documents the field
ANSWERED = "answered"
#: the share of the difference a classic mistake must account for to be named as the nearest explanation
#: (:meth:`Diagnosis.sentence`): "most of" the difference (:func:`.words.share_words`); below it, a mistake the
#: student did not make is named by the little of the difference that happens to look like it
NAMED_SHARE = MOST


def answered(doc: Any, as_type: object = None) -> dict[str, tuple[object, FieldInfo]]:
    """A field's metadata for the service's answer (:func:`service.http.models.answer_model`): its OpenAPI
    documentation and, where the answer's JSON has another type than the record (a field left out when empty is
    optional there), that type."""
    return {ANSWERED: (as_type, doc)}


@dataclass(frozen=True)
class Cause:
    #: a name of tracer.scene.variants.VARIANTS or MORE_VARIANTS; for a nearest explanation that is a term,
    #: ``term:NAME`` or ``term:NAME:LIGHT`` (``term:specular:1``)
    variant: str = field(
        metadata=answered(
            Field(
                examples=["no-shadows"],
                description="a mistake's id; for a nearest explanation that is a term, term:NAME or term:NAME:LIGHT",
            )
        )
    )
    #: what the student did, in words (a nearest explanation: what the difference is)
    mistake: str = field(metadata=answered(Field(examples=["no shadow rays"])))
    #: the submission against the reference rendered with the mistake (or mistakes)
    fraction_off_nearby: float = field(
        metadata=answered(
            Field(
                description="the submission graded against the reference rendered with "
                "the mistake (with the others of a combination)"
            )
        )
    )
    passes: bool = field(metadata=answered(Field(description="the submission passes against that render")))
    #: the other mistakes it was rendered with (a combination); left out of the answer when empty
    together: list[str] = field(
        default_factory=list,
        metadata=answered(
            Field(
                None,
                description="the other mistakes it was rendered with (mistakes made together); absent for a single "
                "mistake",
            ),
            list[str] | None,
        ),
    )
    #: of the submission's difference from the reference, what this accounts for
    share: float | None = field(
        default=None,
        metadata=answered(
            Field(
                None,
                description="of the submission's difference from the reference, what this "
                "accounts for (a combination's or a nearest explanation's)",
            )
        ),
    )
    #: why it is named, in words; left out of the answer when empty
    evidence: str = field(
        default="", metadata=answered(Field(None, description="why it is named, in words"), str | None)
    )

    def as_dict(self) -> dict[str, Any]:
        """As JSON: the four first fields always, the others only when set (a single mistake's are as before)."""
        out = asdict(self)
        for key, empty in (("together", []), ("share", None), ("evidence", "")):
            if out[key] == empty:
                del out[key]
        return out


#: the terms a fit names (the answer's ``name`` takes only these)
TermName = Literal["background", "ambient", "diffuse", "specular", "reflection", "refraction"]


@dataclass(frozen=True)
class Term:
    #: "ambient", "diffuse", "specular", ... ; light-specific ones name their light
    name: str = field(metadata=answered(Field(), TermName))
    light: int | None = field(  # index in scene.lights, or None
        metadata=answered(Field(description="the index in lights of a light's own term"))
    )
    scale: float = field(  # the fitted coefficient: 1 is right
        metadata=answered(Field(description="the fitted coefficient against the reference's term: 1 is right"))
    )
    share: float | None = field(
        default=None,
        metadata=answered(
            Field(None, description="of the submission's difference from the reference, what this term accounts for")
        ),
    )
    words: str = field(  # for a student: "the specular of light 'key' is missing"
        default="",
        metadata=answered(Field("", examples=["the specular of light 'key' is missing"], description="for a student")),
    )


@dataclass(frozen=True)
class Share:
    index: int = field(  # index in scene.objects (or scene.lights)
        metadata=answered(Field(description="the index in objects (or lights); -1 for the background"))
    )
    kind: str = field(metadata=answered(Field()))  # the object's or light's type
    share: float = field(metadata=answered(Field(description="of the failing pixels")))
    words: str = field(  # for a student: "sphere 'ball'", "the third light (area)"
        default="",
        metadata=answered(
            Field(
                "",
                examples=["sphere 'ball'", "the third light (area)"],
                description="for a student: its name in quotes, else its place and kind",
            )
        ),
    )


@dataclass
class Diagnosis:
    #: the first cause is only the closest, not passed against
    closest: bool = field(
        default=False, metadata=answered(Field(description="the first cause is only the closest, not passed against"))
    )
    causes: list[Cause] = field(  # best first; empty when nothing fits
        default_factory=list,
        metadata=answered(Field(description="the mistakes whose render the submission matches, best first")),
    )
    terms: list[Term] = field(  # the terms out of scale
        default_factory=list, metadata=answered(Field(description="the additive terms out of scale, most first"))
    )
    objects: list[Share] = field(
        default_factory=list, metadata=answered(Field(description="what the failing pixels show"))
    )
    lights: list[Share] = field(
        default_factory=list, metadata=answered(Field(description="the lights that fall on the failing pixels"))
    )
    #: why no diagnosis could be made (:func:`unavailable`); None: it was made (the answer says it in its sentence)
    unavailable: str | None = None
    #: the honest offset it was made at, in words ("a ray offset of 0.003 along the normal", :mod:`.nuisance`);
    #: None: against the reference itself
    offset: str | None = field(
        default=None,
        metadata=answered(
            Field(
                None,
                examples=["a ray offset of 0.003 along the normal"],
                description="the honest ray offset the submission's mistakes were named at (its own offset, "
                "fitted); null when they were named against the reference itself",
            )
        ),
    )

    @property
    def together(self) -> bool:
        """The causes are mistakes made together (rendered at once)."""
        return bool(self.causes and self.causes[0].together)

    @property
    def combinations(self) -> list[list[Cause]]:
        """The causes of mistakes made together, by reading of the image: the combination named first, then each
        other combination the image cannot tell from it (none when the causes are not mistakes made together)."""
        return by_reading(self.causes, lambda c: (c.variant, c.together)) if self.together else []

    @property
    def readings(self) -> list[Cause]:
        """The mistakes the image cannot tell apart: every single mistake the submission passes against (each
        renders an image the grade cannot tell from it), when there are two or more; else none."""
        passing = [c for c in self.causes if c.passes and not c.together]
        return passing if len(passing) > 1 else []

    @property
    def nearest(self) -> bool:
        """The causes are only the nearest explanations: none passed against, none the closest."""
        return bool(self.causes) and not self.closest and not any(c.passes for c in self.causes)

    def sentence(self) -> str:
        """One sentence for a person: the likely mistake (or mistakes made together) and the evidence, the
        nearest explanation, or why there is no diagnosis."""
        if self.unavailable is not None:
            return f"No diagnosis: {self.unavailable}"
        if self.nearest:
            named = self._nearest_named()
            if named is None:
                return "No known mistake fits: compare the heat-map with the reference" + self._where()
            return nearest_sentence(named.mistake, named.share or 0.0)
        also = "" if self.offset is None else f" and {self.offset}"
        if self.together:
            first, *others = [[c.mistake for c in made] for made in self.combinations]
            c = self.causes[0]
            return together_sentence(first, c.fraction_off_nearby, c.passes, also, others)
        if self.readings:
            readings = self.readings
            return readings_sentence(
                [c.variant for c in readings], [c.mistake for c in readings], readings[0].fraction_off_nearby
            )
        if self.causes:
            c = self.causes[0]
            how = "matches" if not self.closest else "comes closest to"
            advice = f". {SENTENCES[c.variant]}" if c.variant in SENTENCES else ""  # (a new mistake's advice)
            return (
                f"Likely: {c.mistake} — the submission {how} the reference rendered with that mistake{also} "
                f"({percent(c.fraction_off_nearby)} of pixels off){advice}"
            )
        if self.terms:
            return f"Likely: {term_words(self.terms[0])}"
        return "No known mistake fits: compare the heat-map with the reference"

    def _nearest_named(self) -> Cause | None:
        """The nearest explanation a sentence names: a term out of scale, or a mistake that accounts for
        :data:`NAMED_SHARE` of the difference or more; None where the first is a mistake that accounts for less
        (a spot's cone drawn too narrow is not 'some of what grayscale changes': naming it misleads)."""
        first = self.causes[0]
        return first if first.variant.startswith("term:") or (first.share or 0.0) >= NAMED_SHARE else None

    def _where(self) -> str:
        """ "; the difference is mostly on the first plane, in the light of the second light (point)": the object
        and the light that most of the failing pixels are of, where one is (a light only where another light
        falls on some of them too: the one light of every failing pixel tells nothing of the mistake)."""
        lights = self.lights if len(self.lights) > 1 else []
        places = [
            f"{lead}{top.words}"
            for lead, shares in (("on ", self.objects), ("in the light of ", lights))
            for top in shares[:1]
            if top.share >= 0.5 and top.words and top.index >= 0
        ]
        return f"; the difference is mostly {', '.join(places)}" if places else ""

    def headline(self) -> str:
        """A few words for a report's cell: the likely mistake (mistakes made together joined by +), the nearest
        explanation, the term out of scale, that nothing fits, or why there is no diagnosis."""
        if self.nearest:
            named = self._nearest_named()
            return "no known mistake fits" if named is None else "nearest: " + named.mistake
        if self.readings:  # (what the image cannot tell apart)
            return " or ".join(c.mistake for c in self.readings)
        if self.together:  # (each reading the image cannot tell apart, mistakes made together joined by +)
            said = " or ".join(" + ".join(c.mistake for c in made) for made in self.combinations)
            return said + (" (closest)" if self.closest else "")
        if self.causes:
            return self.causes[0].mistake + (" (closest)" if self.closest else "")
        if self.terms:
            return term_words(self.terms[0])
        return self.sentence() if self.unavailable is not None else "no known mistake fits"

    def worded(self, names: Names) -> Diagnosis:
        """This diagnosis with its terms, objects and lights in a student's words (names in quotes, or places)."""
        self.terms = [replace(t, words=term_sentence(t.name, t.light, t.scale, names)) for t in self.terms]
        self.objects = [replace(s, words=names.object(s.index)) for s in self.objects]
        self.lights = [replace(s, words=names.light(s.index)) for s in self.lights]
        return self

    def as_dict(self) -> dict[str, Any]:
        """As the service and the command line give it (JSON): the sentence, then the evidence, and the offset it
        was made at when it was made at one."""
        out = {
            "sentence": self.sentence(),
            "closest": self.closest,
            "causes": [c.as_dict() for c in self.causes],
            "terms": [asdict(t) for t in self.terms],
            "objects": [asdict(s) for s in self.objects],
            "lights": [asdict(s) for s in self.lights],
        }
        return out if self.offset is None else {**out, "offset": self.offset}

    @classmethod
    def from_dict(cls, found: dict[str, Any]) -> Diagnosis:
        """The record of :meth:`as_dict`'s answer (a class worker's, read back): ``as_dict`` of it is ``found``."""
        sentence: str = found["sentence"]
        why = sentence.removeprefix("No diagnosis: ") if sentence.startswith("No diagnosis: ") else None
        return cls(
            closest=found["closest"],
            causes=[Cause(**c) for c in found["causes"]],
            terms=[Term(**t) for t in found["terms"]],
            objects=[Share(**s) for s in found["objects"]],
            lights=[Share(**s) for s in found["lights"]],
            unavailable=why,
            offset=found.get("offset"),
        )


def term_words(term: Term) -> str:
    """A term out of scale in words: its student's words when it has them ("the specular of light 'key' is
    missing"), else by index ("the diffuse of lights[1] is twice as bright as the reference's")."""
    if term.words:
        return term.words
    return term_sentence(term.name, term.light, term.scale, Names((), ()))


def headline(found: Diagnosis | None) -> str:
    """A diagnosis in a few words, for a report's cell (:meth:`Diagnosis.headline`); empty for none (a pass)."""
    return "" if found is None else found.headline()


def unavailable(why: str) -> Diagnosis:
    """A diagnosis that could not be made, and why."""
    return Diagnosis(unavailable=why)


def matched(diagnosis: dict[str, Any] | None) -> list[str]:
    """The ids of the mistakes a failing image matches (passes against the reference rendered with each), best
    first, from a diagnosis as :meth:`service.diagnosis.Diagnosis.as_dict` gives it; mistakes made together are
    one id, ``no-shadows+gamma`` (two faults: each one's deduction is taken: the gradebook's score), one per
    reading of the image (``no-shadows+no-refraction``, ``no-shadows+exit-normal-not-flipped``: the image cannot
    tell them apart, and a deduction applies to either, as to one of two single mistakes alike)."""
    if not diagnosis:
        return []
    causes = [c for c in diagnosis.get("causes", []) if c.get("passes")]
    if causes and causes[0].get("together"):  # mistakes made together: one id for each reading
        return ["+".join(c["variant"] for c in made) for made in together_readings(causes)]
    return [c["variant"] for c in causes]


def together_readings(causes: list[dict[str, Any]]) -> list[list[dict[str, Any]]]:
    """The causes of mistakes made together (as :meth:`Cause.as_dict` gives them) by reading of the image: the
    combination named first, then each other the image cannot tell from it."""
    return by_reading(causes, lambda c: (c["variant"], c.get("together") or []))


Made = TypeVar("Made")


def by_reading(causes: list[Made], names: Callable[[Made], tuple[str, list[str]]]) -> list[list[Made]]:
    """``causes`` grouped by the mistakes each was made together with (``names``: its own and the others'), in
    their order: one group per reading of the image."""
    groups: dict[frozenset[str], list[Made]] = {}
    for c in causes:
        variant, together = names(c)
        groups.setdefault(frozenset((variant, *together)), []).append(c)
    return list(groups.values())
