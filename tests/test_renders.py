"""What a diagnosis renders (service/diagnosis/renders.py): the scene's own renders and the same renders seen as
whole images only give the same rows, far ends and failing pixels' passes."""

import numpy as np
import pytest

import schemas
from bench.pricing import own_scene
from bench.scenes import example
from service.diagnosis import Cached, WholeImages, accepting, renders_of, settled, too_large
from service.diagnosis.looks import off_rows, telling_middles
from service.diagnosis.rendered import options_of
from service.images.grading import grade
from service.images.nearby import rows_distance
from service.work import pipeline
from tracer import RenderCancelled, Renderer
from tracer.scene.variants import BOUNDS, VARIANTS


def _folded(renders, pixels):
    parts = []
    found = renders.at(pixels, lambda first, part: parts.append((first, part)))
    return found, parts


def test_whole_images_give_the_rows_far_ends_and_pixels_the_scene_renders_alone():
    scene = schemas.validate_scene(example("01_three_spheres", 24, 16))
    alone, whole = renders_of(scene, threads=1), WholeImages(renders_of(scene, threads=1))
    rows = np.array([0, 5, 6, 15])
    for name in ("no-shadows", "gamma", "offset-too-large@0.05"):
        assert np.array_equal(whole.rows(name, rows), alone.rows(name, rows)), name
        own = Renderer(scene, options_of(name, alone.size)).pixels()
        assert np.array_equal(whole.rows(name, rows), own[rows]), name
    assert np.array_equal(whole.bound_rows("shadow-acne", rows), Renderer(scene, BOUNDS["shadow-acne"]).pixels()[rows])
    assert not any(whole.unchanged(name) for name in VARIANTS)  # (every mistake scored, shown or not)
    pixels = np.array([3, 40, 41, 200, 24 * 16 - 1])
    (found_alone, parts_alone), (found_whole, parts_whole) = _folded(alone, pixels), _folded(whole, pixels)
    assert np.array_equal(found_alone, found_whole)
    lights = [k for k, light in enumerate(scene.lights) if light.type != "ambient"]
    assert lights and len(parts_whole) == 1 and parts_whole[0][0] == 0
    for k in lights:
        for term in ("diffuse", "specular"):
            got = np.concatenate([part[f"{term}:{k}"] for _, part in parts_alone])
            assert np.array_equal(parts_whole[0][1][f"{term}:{k}"], got), (term, k)


def test_a_cancel_set_on_whole_images_stops_the_renders_they_stand_for():
    scene = schemas.validate_scene(example("01_three_spheres", 8, 6))
    inner = renders_of(scene, threads=1)
    whole = WholeImages(inner)
    whole.cancel = lambda: True
    assert inner.cancel is whole.cancel
    with pytest.raises(RenderCancelled):
        whole.check()


def test_a_grade_renders_each_rung_of_the_offsets_ladders_once_in_the_one_cache(monkeypatch):
    """A mistaken image is graded against the accepted offsets' ladder, then diagnosed against the ladder of offsets
    too large, which starts at the accepted ladder's top: that rung's pixels, like every other's, are rendered once
    (whether alone, near those a look counts, or as rows), and kept with the scene's renders for diagnosis (counted
    in the cache's one budget)."""
    scene = schemas.validate_scene(example("04_whitted", 80, 60))
    reference = Renderer(scene).pixels()
    wrong = Renderer(scene, VARIANTS["no-shadows"][0]).pixels()
    rendered: list[tuple[object, int]] = []
    original = Renderer.pixels_at

    def pixels_once(self, pixels, *args, **kwargs):  # noqa: ANN001, ANN002, ANN003, ANN202
        rendered.extend((self.options, int(p)) for p in pixels)
        return original(self, pixels, *args, **kwargs)

    monkeypatch.setattr(Renderer, "pixels_at", pixels_once)
    monkeypatch.setattr(accepting, "KEPT_RENDERS", accepting._Kept())
    cache = Cached()
    checking = pipeline.Checking(threads=1, cache=cache)
    graded = pipeline.explain(scene, pipeline.Graded(grade(reference, wrong, ""), None), reference, wrong, run=checking)
    assert graded.diagnosis is not None and graded.diagnosis.causes[0].variant == "no-shadows"
    assert rendered and len(rendered) == len(set(rendered))  # (no pixel of any render twice)
    size = cache.held[next(iter(cache.held))].size()
    shared = options_of(too_large.rung_name(too_large.amounts(size)[0]), lambda: size)
    top = next(r for r in accepting.accepted_ladders(scene, None) if r[0].kind == "normal-offset")[-1]
    assert shared == top.options and any(options == shared for options, _ in rendered)
    assert not accepting.KEPT_RENDERS.rows  # (kept with the scene's renders, in their budget)


def test_a_mistakes_accepted_ladders_are_given_up_having_rendered_only_pixels_near_those_off(monkeypatch):
    """A no-shadows image fails the accepted t_min ladder on the rows where it is most off: each rung is rendered
    there only within the reach of a count (:func:`service.diagnosis.settled.windows`) of the pixels off against
    the reference, never whole rows (the ladder along the normal is not given up so soon in this scene)."""
    scene = schemas.validate_scene(example("04_whitted", 80, 60))
    reference = Renderer(scene).pixels()
    wrong = Renderer(scene, VARIANTS["no-shadows"][0]).pixels()
    rendered: dict[object, list[int]] = {}
    original = Renderer.pixels_at

    def recorded(self, pixels, *args, **kwargs):  # noqa: ANN001, ANN002, ANN003, ANN202
        rendered.setdefault(self.options, []).extend(int(p) for p in pixels)
        return original(self, pixels, *args, **kwargs)

    monkeypatch.setattr(Renderer, "pixels_at", recorded)
    monkeypatch.setattr(accepting, "KEPT_RENDERS", accepting._Kept())
    failing = accepting.Failing(reference, wrong, grade(reference, wrong, ""))
    assert accepting.accept(scene, failing, threads=1, renders=renders_of(scene, threads=1)) is None
    counts = off_rows(reference, wrong, 2.0)
    middles = telling_middles(counts, np.inf)
    off = np.zeros(reference.shape[:2], dtype=bool)
    off[middles] = off_pixels_of(reference, wrong)[middles]
    near = settled.windows(off[middles], middles, reference.shape[0]).ravel()
    rungs = [pixels for options, pixels in rendered.items() if options.offset_along == "ray"]  # type: ignore[attr-defined]
    assert len(rungs) > 1 and all(near[pixels].all() for pixels in rungs)
    assert all(len(set(pixels)) == len(pixels) < 3 * len(middles) * reference.shape[1] for pixels in rungs)


def off_pixels_of(reference: np.ndarray, submitted: np.ndarray) -> np.ndarray:
    """``(H, W)``: the pixels of ``submitted`` off even nearby against ``reference`` (at the default tolerance)."""
    rows = np.arange(1, reference.shape[0] - 1)
    bands = [
        image[(rows[:, None] + np.arange(-1, 2)[None, :]).ravel()].reshape(len(rows), 3, -1, 3)
        for image in (reference, submitted)
    ]
    off = np.zeros(reference.shape[:2], dtype=bool)
    off[rows] = rows_distance(bands[0], bands[0], bands[1]) > 2.0
    return off


def test_a_look_on_more_rows_renders_there_only_the_rungs_the_first_look_left_open(monkeypatch):
    """The accepted ladder along the normal, looked at on more rows after a first look left a pair of rungs open
    (the Cornell homework, no shadows): the rungs below that pair settled it already and render nothing on the
    rows added; the pair's rungs do."""
    scene = schemas.validate_scene(own_scene(1, 100))
    reference = Renderer(scene).pixels()
    wrong = Renderer(scene, VARIANTS["no-shadows"][0]).pixels()
    rendered: dict[object, list[int]] = {}
    looks: list[tuple[np.ndarray, int, int | None]] = []
    original, unsettled = Renderer.pixels_at, accepting._unsettled

    def recorded(self, pixels, *args, **kwargs):  # noqa: ANN001, ANN002, ANN003, ANN202
        rendered.setdefault(self.options, []).extend(int(p) for p in pixels)
        return original(self, pixels, *args, **kwargs)

    def looked(scene, pair, rungs, look, allowed, start):  # noqa: ANN001, ANN202
        left = unsettled(scene, pair, rungs, look, allowed, start)
        looks.append((look.looked(pair.submitted.shape[0])[1], start, left))
        return left

    monkeypatch.setattr(Renderer, "pixels_at", recorded)
    monkeypatch.setattr(accepting, "_unsettled", looked)
    monkeypatch.setattr(accepting, "KEPT_RENDERS", accepting._Kept())
    failing = accepting.Failing(reference, wrong, grade(reference, wrong, ""))
    assert accepting.accept(scene, failing, threads=1, renders=renders_of(scene, threads=1)) is None
    (first_rows, _, left), (more_rows, start, settled_there) = looks[:2]  # (the ladder along the normal)
    assert left is not None and start == left > 2 and settled_there is None
    ladder = next(r for r in accepting.accepted_ladders(scene, None) if r[0].kind == "normal-offset")
    added = np.setdiff1d(more_rows, first_rows)
    rows_of = {rung.options: set((np.array(rendered[rung.options]) // 100).tolist()) for rung in ladder}
    assert all(not rows_of[rung.options] & set(added.tolist()) for rung in ladder[: start - 2])
    assert all(rows_of[rung.options] & set(added.tolist()) for rung in ladder[start - 2 :])
