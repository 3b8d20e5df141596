"""The differential fuzz test, CI's subset: generated scenes against the float64 brute force.

A few hundred scenes of :mod:`generator` at tiny sizes, each compared ray by
ray and pixel by pixel (:mod:`fuzz`), on every core: camera rays, mirror rays
leaving the hit surfaces (the walk from a surface) and shadow rays; the camera,
mirror and shadow rays also by :mod:`tracer.proofs.cones`' pairs, against the walk,
bit for bit; and every shadow ray the lights' proofs (:mod:`tracer.proofs.culling`)
decide without casting, cast.  A soak of thousands is ``python -m tests.fuzz
--scenes 10000``.
"""

import os
from concurrent.futures import ProcessPoolExecutor

import pytest

import fuzz
import generator

#: scenes per CI run (``PHONGRAY_FUZZ_SCENES`` may change it), and the first seed: a fixed set, so that a failure
#: reproduces
SCENES = int(os.environ.get("PHONGRAY_FUZZ_SCENES") or 800)
FIRST = 0


@pytest.fixture(scope="module")
def outcomes():
    with ProcessPoolExecutor(max_workers=min(4, os.cpu_count() or 1)) as pool:
        return list(pool.map(fuzz.run_seed, range(FIRST, FIRST + SCENES), chunksize=4))


def test_every_family_is_in_the_subset(outcomes):
    seen = {o.family.split("+")[0] for o in outcomes}
    assert seen == set(generator.FAMILIES)
    assert sum("+moved" in o.family for o in outcomes) > SCENES // 5


def test_the_brute_force_is_clear_on_most_of_what_it_compares(outcomes):
    # a check of the check: the comparisons below must not be vacuous
    total = {
        k: sum(o.compared[k] for o in outcomes)
        for k in (
            "hit",
            "mirror hit",
            "shadow",
            "pixel",
            "open pixel",
            "hit by cones",
            "hit by lines",
            "shadow by cones",
            "shadow by proofs",
        )
    }
    assert total["hit"] > 0.9 * SCENES * 20 * 15
    assert total["pixel"] > 0.8 * SCENES * 20 * 15
    assert total["shadow"] > SCENES * 100
    # the cones' pairs are checked against the walk on most scenes' camera and shadow rays
    assert total["hit by cones"] > 0.9 * SCENES * 20 * 15
    assert total["shadow by cones"] > 0.8 * total["shadow"]
    # mirror rays from the hit surfaces, the lines' pairs, and the rays the proofs decide
    assert total["mirror hit"] > SCENES * 150
    assert total["hit by lines"] > SCENES * 400
    assert total["shadow by proofs"] > SCENES * 50
    # the pixels a tie between surfaces in one plane leaves open (the contact scenes')
    assert total["open pixel"] > SCENES // 20


def test_phongray_agrees_with_the_brute_force_on_every_generated_scene(outcomes):
    bad = [o for o in outcomes if o.bad]
    report = "\n".join(
        f"seed {o.seed} ({o.family}): {o.error or dict(o.disagreed)}; " + "; ".join(o.examples[:2]) for o in bad[:10]
    )
    assert not bad, (
        f"{len(bad)} of {SCENES} scenes disagree (rerun one with python -m tests.fuzz --scenes 1 --seed N):\n{report}"
    )
