"""What a failing submission most likely got wrong: named mistakes, terms out of scale, and where.

Three kinds of evidence, each from renders of the reference scene:

* **Variants.** The reference rendered with each classic mistake
  (:data:`tracer.scene.variants.VARIANTS`, and where the terms point, those of
  ``MORE_VARIANTS``), graded against the submission with the same measure as
  the grade itself.  A variant the submission passes against is a likely
  cause; two or three made together are found by fitting the sum of their
  differences and confirmed by one render of them all (:mod:`.compose`);
  when none passes, one that comes far closer than the reference does is
  named as the closest, and otherwise the nearest explanations are ranked by
  their share of the difference (:mod:`.together`).
* **Terms.** A non-negative least-squares fit of the submission's linear
  values against the reference's additive passes (background, ambient, each
  light's diffuse and specular, reflection, refraction), on the pixels neither
  image clips: a coefficient far from 1 says a term is too strong or too weak,
  and by how much.
* **Where.** The objects the failing pixels show (the object pass), and the
  lights whose light falls on them.

Everything here is pure: the renders come in through a :class:`Renders`.  The modules, one concept each:
:mod:`.records` (what a diagnosis says, and its words), :mod:`.renders` (what it needs rendered, as a protocol),
:mod:`.causes` (the variants scored, :func:`diagnose`), :mod:`.looks` (variants ruled out from a few rows),
:mod:`.fit` (the terms out of scale), :mod:`.where` (the objects and lights), :mod:`.rendered` (the renders
of a scene, made when first asked for), :mod:`.cache` (those of the last few scenes, kept) and
:mod:`.accepting` (the accepted variants a failing image is graded against before it is diagnosed),
:mod:`.compose` and :mod:`.stored` (mistakes made together; mistakes of the stored image, found without a
render), :mod:`.together` (the nearest explanations), :mod:`.nuisance` (a mistake behind an honest offset),
:mod:`.behind` (a mistake behind another) and :mod:`.words` (names and scales in a student's
words).
"""

from .cache import CACHE, Cached
from .causes import diagnose
from .looks import sampled_rows
from .records import Cause, Diagnosis, Share, Term, headline, term_words, unavailable
from .rendered import renders_needed, renders_of
from .renders import Renders, WholeImages

__all__ = [
    "CACHE",
    "Cached",
    "Cause",
    "Diagnosis",
    "Renders",
    "Share",
    "Term",
    "WholeImages",
    "diagnose",
    "headline",
    "renders_needed",
    "renders_of",
    "sampled_rows",
    "term_words",
    "unavailable",
]
