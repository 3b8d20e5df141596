"""A diagnosis bounded in memory and time (issue 44): the term fit and the lights' shares taken a block of
pixels at a time, never a matrix of lights × pixels; its cache counted; its stages stopped by their cancel."""

import time
import tracemalloc

import numpy as np
import pytest

import schemas
from bench.answers import many_lights as bench_scene
from service.diagnosis import Cached, diagnose, fit, rendered, renders_of
from service.images.grading import grade
from tracer import RenderCancelled, Renderer


def many_lights(lights: int, width: int = 160, height: int = 120) -> dict:
    """A floor and a ball under a grid of dim point lights (and an ambient one): the bench's attack scene, smaller."""
    return bench_scene(lights, width, height, columns=8, colour=0.02)


@pytest.fixture(scope="module")
def crowd():
    scene = schemas.validate_scene(many_lights(96))
    reference = Renderer(scene).pixels()
    noise = np.random.default_rng(1).integers(0, 256, reference.shape, dtype=np.uint8)
    return scene, reference, noise


@pytest.fixture(scope="module")
def noisy(crowd):
    """The diagnosis of the crowd's noisy image, under tracemalloc: what it found, its peak of traced memory, and
    the renders it used.  Its two checks (the peak, and the arrays a cache of those renders counts) read the one
    diagnosis: each took a diagnosis of the same image of the same scene, the same work twice."""
    scene, reference, noise = crowd
    renders = renders_of(scene)
    tracemalloc.start()
    try:
        found = diagnose(reference, noise, grade(reference, noise, ""), renders)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return found, peak, renders


def test_a_many_light_diagnosis_holds_no_matrix_of_lights_by_pixels(crowd, noisy):
    # the attack: a noisy image of a scene of many lights.  Its lights' terms alone, one plane each, are
    # pixels × 3 × 8 bytes × 2 × 96 lights = 85 MiB here; the fit's matrix of them as much again (the worker went
    # from 1.5 to 5.8 GB at 640×480 with 100 lights).  Now the peak is a few chunks' worth
    _, reference, _ = crowd
    found, peak, _ = noisy
    planes = reference.shape[0] * reference.shape[1] * 3 * 8 * 2 * 96
    assert found.sentence()  # (a diagnosis, whatever it says)
    assert peak < planes, f"peak {peak / 2**20:.1f} MiB against {planes / 2**20:.1f} MiB of lights' planes"


def _students_without_light_one(scene):
    dim = scene.model_copy(update={"lights": [light for k, light in enumerate(scene.lights) if k != 1]})
    return Renderer(dim).pixels()


def test_the_fit_in_blocks_finds_the_terms_the_one_matrix_finds(monkeypatch):
    # a light left out: a term missing.  Solved on the matrix of its used values, and (forced) on the Gram
    # matrix summed block by block from passes rendered again and folded: the same terms, the same scales to
    # rounding
    scene = schemas.validate_scene(many_lights(16, 96, 72))
    reference = Renderer(scene).pixels()
    wrong = _students_without_light_one(scene)
    verdict = grade(reference, wrong, "")
    whole = diagnose(reference, wrong, verdict, renders_of(scene)).terms
    monkeypatch.setattr(fit, "FIT_MATRIX_BYTES", 0)
    monkeypatch.setattr(rendered, "WHOLE_PASSES_BYTES", 0)
    folded = diagnose(reference, wrong, verdict, renders_of(scene)).terms
    assert whole and [(t.name, t.light) for t in folded] == [(t.name, t.light) for t in whole]
    assert np.allclose([t.scale for t in folded], [t.scale for t in whole], rtol=0, atol=1e-6)


def test_a_cancel_stops_the_fit_between_its_blocks(crowd, monkeypatch):
    # the fit polled no deadline: a diagnosis answered 17.6 s after a 5 s render_timeout.  Cancel once the fit
    # has begun (its first block): the diagnosis stops there, with RenderCancelled
    scene, reference, noise = crowd
    renders = renders_of(scene)
    began = []
    real = fit._Fit.fold

    def fold(self, first, part):
        began.append(first)
        return real(self, first, part)

    monkeypatch.setattr(fit._Fit, "fold", fold)
    renders.cancel = lambda: bool(began)
    started = time.monotonic()
    with pytest.raises(RenderCancelled):
        diagnose(reference, noise, grade(reference, noise, ""), renders)
    assert began == [0], began  # (stopped at its first block: no second one was folded)
    assert time.monotonic() - started < 600


def test_the_diagnosis_cache_counts_its_arrays_and_keeps_within_its_room(crowd, noisy):
    _, reference, _ = crowd
    room = [1 << 40]
    cache = Cached(room=lambda: room[0])
    cache.get("crowd", lambda: noisy[2])  # (the renders of a diagnosis of the noisy image, over)
    cache.trim()
    held = cache.size
    # the variants' images it holds at least (uint8), and nothing near the lights' planes
    assert reference.nbytes <= held < reference.shape[0] * reference.shape[1] * 3 * 8 * 2 * 96 / 4
    assert len(cache) == 1
    room[0] = held - 1  # less room than it holds: the scene is let go
    cache.trim()
    assert len(cache) == 0 and cache.size == 0
