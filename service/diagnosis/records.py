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

    def sentence(self) -> str:
        """One sentence for a person: the likely mistake and the evidence, or that nothing fits."""
        if self.causes:
            c = self.causes[0]
            how = "matches" if not self.closest else "comes closest to"
            return (f"Likely: {c.mistake} — the submission {how} the reference rendered with that mistake "
                    f"({percent(c.fraction_off_nearby)} of pixels off)")
        if self.terms:
            return f"Likely: {term_words(asdict(self.terms[0]))} (about ×{self.terms[0].scale:.2f} of the reference's)"
        return "No known mistake fits: compare the heat-map with the reference"

    def as_dict(self) -> dict[str, Any]:
        return {"sentence": self.sentence(), "closest": self.closest,
                "causes": [asdict(c) for c in self.causes], "terms": [asdict(t) for t in self.terms],
                "objects": [asdict(s) for s in self.objects], "lights": [asdict(s) for s in self.lights]}


def term_words(term: dict[str, Any]) -> str:
    """``the diffuse of light 1 term is missing`` for a term (as :meth:`Diagnosis.as_dict` lists it)."""
    what = term["name"] if term["light"] is None else f"{term['name']} of light {term['light']}"
    how = "missing" if term["scale"] < MISSING else "too strong" if term["scale"] > 1 else "too weak"
    return f"the {what} term is {how}"


def headline(found: dict[str, Any] | None) -> str:
    """A diagnosis (as :meth:`Diagnosis.as_dict`) in a few words, for a report's cell: the likely mistake,
    the term out of scale, or that nothing fits; empty for none (a pass)."""
    if not found:
        return ""
    if found["causes"]:
        return found["causes"][0]["mistake"] + (" (closest)" if found["closest"] else "")
    if found["terms"]:
        return f"{term_words(found['terms'][0])} (×{found['terms'][0]['scale']:.2f})"
    sentence: str = found["sentence"]
    return sentence if sentence.startswith("No diagnosis") else "no known mistake fits"


def unavailable(why: str) -> dict[str, Any]:
    """A diagnosis (as :meth:`Diagnosis.as_dict`) that could not be made, and why."""
    return {**Diagnosis().as_dict(), "sentence": f"No diagnosis: {why}"}

