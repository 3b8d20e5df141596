"""What a diagnosis says: its causes, the terms out of scale, the objects and lights where the failing pixels
are, and the words for it (a sentence for a person, a headline for a report's cell)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from ..display import percent

#: a term fitted below this is missing, not just too weak
MISSING = 0.05


@dataclass(frozen=True)
class Cause:
    variant: str  # a name of tracer.variants.VARIANTS
    mistake: str  # what the student did, in words
    fraction_off_nearby: float  # the submission against the reference rendered with the mistake
    passes: bool  # the submission passes against that render


@dataclass(frozen=True)
class Term:
    name: str  # "ambient", "diffuse", "specular", ... ; light-specific ones name their light
    light: int | None  # index in scene.lights, or None
    scale: float  # the fitted coefficient: 1 is right


@dataclass(frozen=True)
class Share:
    index: int  # index in scene.objects (or scene.lights)
    kind: str  # the object's or light's type
    share: float  # of the failing pixels


@dataclass
class Diagnosis:
    causes: list[Cause] = field(default_factory=list)  # best first; empty when nothing fits
    closest: bool = False  # the first cause is only the closest, not passed against
    terms: list[Term] = field(default_factory=list)  # the terms out of scale
    objects: list[Share] = field(default_factory=list)
    lights: list[Share] = field(default_factory=list)
    unavailable: str | None = None  # why no diagnosis could be made (:func:`unavailable`); None: it was made

    def sentence(self) -> str:
        """One sentence for a person: the likely mistake and the evidence, that nothing fits, or why there is no
        diagnosis."""
        if self.unavailable is not None:
            return f"No diagnosis: {self.unavailable}"
        if self.causes:
            c = self.causes[0]
            how = "matches" if not self.closest else "comes closest to"
            return (f"Likely: {c.mistake} — the submission {how} the reference rendered with that mistake "
                    f"({percent(c.fraction_off_nearby)} of pixels off)")
        if self.terms:
            return f"Likely: {term_words(self.terms[0])} (about ×{self.terms[0].scale:.2f} of the reference's)"
        return "No known mistake fits: compare the heat-map with the reference"

    def headline(self) -> str:
        """A few words for a report's cell: the likely mistake, the term out of scale, that nothing fits, or why
        there is no diagnosis."""
        if self.causes:
            return self.causes[0].mistake + (" (closest)" if self.closest else "")
        if self.terms:
            return f"{term_words(self.terms[0])} (×{self.terms[0].scale:.2f})"
        return self.sentence() if self.unavailable is not None else "no known mistake fits"

    def as_dict(self) -> dict[str, Any]:
        """As the service and the command line give it (JSON): the sentence, then the evidence."""
        return {"sentence": self.sentence(), "closest": self.closest,
                "causes": [asdict(c) for c in self.causes], "terms": [asdict(t) for t in self.terms],
                "objects": [asdict(s) for s in self.objects], "lights": [asdict(s) for s in self.lights]}

    @classmethod
    def from_dict(cls, found: dict[str, Any]) -> Diagnosis:
        """The record of :meth:`as_dict`'s answer (a class worker's, read back): ``as_dict`` of it is ``found``."""
        sentence: str = found["sentence"]
        why = sentence.removeprefix("No diagnosis: ") if sentence.startswith("No diagnosis: ") else None
        return cls([Cause(**c) for c in found["causes"]], found["closest"], [Term(**t) for t in found["terms"]],
                   [Share(**s) for s in found["objects"]], [Share(**s) for s in found["lights"]], why)


def term_words(term: Term) -> str:
    """``the diffuse of light 1 term is missing`` for a term."""
    what = term.name if term.light is None else f"{term.name} of light {term.light}"
    how = "missing" if term.scale < MISSING else "too strong" if term.scale > 1 else "too weak"
    return f"the {what} term is {how}"


def headline(found: Diagnosis | None) -> str:
    """A diagnosis in a few words, for a report's cell (:meth:`Diagnosis.headline`); empty for none (a pass)."""
    return "" if found is None else found.headline()


def unavailable(why: str) -> Diagnosis:
    """A diagnosis that could not be made, and why."""
    return Diagnosis(unavailable=why)
