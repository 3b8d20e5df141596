"""Diagnosis (service/diagnosis/): a failing submission's likely mistake, terms out of scale, and where."""

import copy

import numpy as np
import pytest
import student
from test_variants import EVERYTHING

import schemas
from service.diagnosis import WholeImages, diagnose, renders_of
from service.diagnosis.fit import nnls
from service.diagnosis.where import where as diagnosis_where
from service.images.grading import grade
from tracer import Renderer
from tracer.image import quantize
from tracer.scene.variants import BOUNDS, VARIANTS
from tracer.shade.passes import ADDITIVE

from helpers import share_renders, smooth_octahedron


@pytest.fixture(scope="module")
def setting():
    scene = schemas.validate_scene(EVERYTHING)
    reference = Renderer(scene).pixels()
    return scene, reference, renders_of(scene)


@pytest.mark.parametrize(
    "name",
    [
        "no-shadows",
        "blinn-phong",
        "gamma",
        "no-attenuation",
        "image-flipped",
        "area-not-divided",
        "spot-radians",
        "no-ambient",
    ],
)
def test_a_students_mistake_is_named_first(setting, name):
    scene, reference, renders = setting
    student = Renderer(scene, VARIANTS[name][0]).pixels()
    verdict = grade(reference, student, "")
    assert not verdict.passed
    found = diagnose(reference, student, verdict, renders)
    assert found.causes[0].variant == name and not found.closest
    assert found.sentence().startswith(f"Likely: {VARIANTS[name][1]}")


def test_a_term_too_weak_is_measured(setting):
    scene, reference, renders = setting
    p = Renderer(scene).passes(list(ADDITIVE), None)
    lights = [Renderer(scene).passes(["diffuse"], k)["diffuse"] for k in (1, 2)]
    linear = sum(p[k] for k in ADDITIVE) - 0.5 * lights[0]  # light 1's diffuse at half strength
    student = quantize(linear)
    verdict = grade(reference, student, "")
    found = diagnose(reference, student, verdict, renders)
    first = found.terms[0]
    assert (first.name, first.light) == ("diffuse", 1) and abs(first.scale - 0.5) < 0.05


def test_a_pass_gets_no_diagnosis_and_noise_fits_nothing(setting):
    scene, reference, renders = setting
    assert diagnose(reference, reference, grade(reference, reference, ""), renders).causes == []
    noise = np.random.default_rng(1).integers(0, 256, reference.shape, dtype=np.uint8)
    found = diagnose(reference, noise, grade(reference, noise, ""), renders)
    assert not any(c.passes for c in found.causes) and not found.closest
    assert found.sentence().startswith(("No known mistake fits", "Likely: the"))


def test_where_names_the_objects_the_failing_pixels_show(setting):
    scene, reference, renders = setting
    student = reference.copy()
    obj = Renderer(scene).passes(["object"])["object"]
    student[obj == 3] = 0  # the small ball black
    found = diagnose(reference, student, grade(reference, student, ""), renders)
    assert found.objects[0].index == 3 and found.objects[0].kind == "sphere" and found.objects[0].share > 0.9


def test_nnls_is_non_negative_and_exact_where_it_can_be():
    rng = np.random.default_rng(2)
    a = rng.random((200, 5))
    x = np.array([0.5, 0.0, 2.0, 1.0, 0.0])
    assert np.allclose(nnls(a, a @ x), x, atol=1e-9)
    y = nnls(a, a @ np.array([1.0, -1.0, 0, 0, 0]))
    assert np.all(y >= 0)


# -- a student's renderer (tests/student.py), each mistake made the student's way ---------------------------


def classroom() -> dict[str, dict]:
    """Three scenes that every mistake of the list changes: anti-aliased, every light type (a spot with a soft
    edge), glass, a mirror that shows the sky, a checkerboard and a smooth mesh."""
    a = copy.deepcopy(EVERYTHING)
    a["image"] = EVERYTHING["image"] | {"width": 64, "height": 48, "samples": 2}
    a["lights"][2]["inner_cutoff"] = 16
    a["objects"][4]["material"] = "tiles"  # the triangle at the back
    a["materials"]["tiles"] = {"diffuse": [0.6, 0.5, 0.4], "specular": 0.7, "shininess": 30}
    a["materials"]["tiles"]["checker"] = {"size": 0.4, "material": "dark"}
    a["materials"]["dark"] = {"diffuse": [0.1, 0.1, 0.3], "specular": 0.5, "shininess": 10}
    a["objects"].append(smooth_octahedron((1.6, 0.45, 1.2), 0.45, "m"))
    b = copy.deepcopy(a)
    b["camera"] = {"position": [-2.5, 1.5, 4.5], "look_at": [0.3, 0.5, 0], "fov": 50}
    b["lights"][1]["position"] = [2, 5, 2]
    c = copy.deepcopy(a)
    c["camera"] = {"position": [1.5, 3.5, 4], "look_at": [-0.2, 0.4, 0], "fov": 40}
    c["materials"]["m"]["checker"] = {"size": 0.5, "material": "dark"}
    c["objects"][4]["material"] = "m"  # (checkered with the rest)
    return {"front": a, "side": b, "checker": c}


@pytest.fixture(scope="module", params=sorted(classroom()))
def room(request):
    scene = schemas.validate_scene(classroom()[request.param])
    return scene, Renderer(scene).pixels(), renders_of(scene)


def test_the_students_correct_image_passes_and_gets_no_diagnosis(room):
    scene, reference, renders = room
    right = student.render(scene)
    verdict = grade(reference, right, "")
    assert verdict.passed and diagnose(reference, right, verdict, renders).causes == []


@pytest.mark.parametrize("mistake", student.MISTAKES)
def test_each_of_the_students_mistakes_is_named_first(room, mistake):
    scene, reference, renders = room
    wrong = student.render(scene, [mistake])
    verdict = grade(reference, wrong, "")
    assert not verdict.passed
    found = diagnose(reference, wrong, verdict, renders)
    assert found.causes and found.causes[0].variant == mistake and not found.closest, found.causes[:3]


def test_a_light_left_out_is_no_named_mistake_but_a_term(room):
    scene, reference, renders = room
    dim = scene.model_copy(update={"lights": [light for k, light in enumerate(scene.lights) if k != 1]})
    wrong = student.render(dim)
    found = diagnose(reference, wrong, grade(reference, wrong, ""), renders)
    assert not any(c.passes for c in found.causes)
    assert (found.terms[0].name, found.terms[0].light) in (("diffuse", 1), ("specular", 1))
    assert found.terms[0].scale < 0.15
    # the nearest explanation, ranked first by its share of the difference, in a student's words
    assert found.closest or found.causes[0].variant in ("term:diffuse:1", "term:specular:1")
    assert (
        found.sentence().startswith(
            (
                "No known mistake fits exactly: most of the difference is the diffuse of "
                "the second light (point), which is missing",
                "No known mistake fits exactly: most of the difference is the specular of "
                "the second light (point), which is missing",
            )
        )
        or found.closest
    )


def test_the_mistakes_are_the_variants():
    assert set(student.MISTAKES) == set(VARIANTS)


# -- what a diagnosis renders: one pass render, variants from the reference's colour, a first look at rows --------


def test_variants_made_from_the_reference_colour_are_their_own_renders(setting):
    scene, reference, renders = setting
    renders.passes(["ambient"], None)  # (made from the colour once the pass render is there)
    for name in ("gamma", "image-flipped"):
        assert np.array_equal(renders.variant(name), Renderer(scene, VARIANTS[name][0]).pixels()), name


def test_one_pass_render_gives_every_lights_terms_as_their_own_renders_do(setting):
    scene, reference, renders = setting
    for k, light in enumerate(scene.lights):
        if light.type == "ambient":
            continue
        own = Renderer(scene).passes(["diffuse", "specular"], k)
        got = renders.passes(["diffuse", "specular"], k)
        assert all(np.array_equal(own[t], got[t]) for t in own), k
    every = Renderer(scene).passes(["background", "ambient", "reflection", "refraction", "object"], None)
    got = renders.passes(list(every), None)
    assert all(np.array_equal(every[t], got[t]) for t in every)


def _submissions(scene, reference):
    out = {
        name: Renderer(scene, VARIANTS[name][0]).pixels()
        for name in ("no-shadows", "blinn-phong", "no-half-pixel", "normals-not-flipped", "gamma")
    }
    out["half as bright"] = reference // 2
    patch = reference.copy()
    patch[10:20, 5:30] = 255
    out["a patch"] = patch
    out["noise"] = np.random.default_rng(4).integers(0, 256, reference.shape, dtype=np.uint8)
    return out


def _blindly(reference, submitted, verdict, blind, monkeypatch):  # noqa: ANN001, ANN202
    """The diagnosis with ``blind`` (:class:`WholeImages`: every variant, the far end and the passes rendered
    whole, every variant scored) and no first look at a few rows (each variant graded on its whole image)."""
    from service.diagnosis import looks

    with monkeypatch.context() as patched:
        patched.setattr(looks, "_looks", lambda *args, **kwargs: [])
        return diagnose(reference, submitted, verdict, blind)


def test_a_first_look_at_a_few_rows_changes_no_diagnosis_and_spares_renders(monkeypatch):
    from service.diagnosis import looks

    # each submission's diagnosis starts from nothing (its own renders, to count the whole ones it asks for);
    # the rows they render are the same rows, made once (what is counted is asked for, not how it is rendered)
    share_renders(monkeypatch)
    scene = schemas.validate_scene(EVERYTHING)
    reference = Renderer(scene).pixels()
    submissions = _submissions(scene, reference)
    # blind: every variant, the far end and the passes rendered whole, and every variant scored; one for every
    # submission, as the service keeps one scene's renders for all (each rendered once, the same pixels)
    blind = WholeImages(renders_of(scene))
    whole_far = Renderer(scene, BOUNDS["shadow-acne"]).pixels().astype(int)
    graded_by = {v: Renderer(scene, VARIANTS[v][0]).pixels() for v in ("no-shadows", "blinn-phong", "no-ambient")}
    spared = 0
    for name, submitted in submissions.items():
        verdict = grade(reference, submitted, "")
        looked = renders_of(scene)
        whole = []
        render_variant = looked.variant
        looked.variant = lambda v, f=render_variant, whole=whole: whole.append(v) or f(v)
        far = []
        render_bound = looked.bound
        looked.bound = lambda v, f=render_bound, far=far: far.append(v) or f(v)
        assert (
            diagnose(reference, submitted, verdict, looked).as_dict()
            == _blindly(reference, submitted, verdict, blind, monkeypatch).as_dict()
        ), name
        spared += len(VARIANTS) - len(whole) + 1 - len(far)
        # and the first look at the far end's rows is a lower bound of what the whole of it counts
        least = looks.outside_at_least("shadow-acne", reference, submitted, verdict, looked)
        outside = looks.speckled(reference, looked.bound("shadow-acne"), submitted, verdict.tolerance)
        ref, sub, tol = reference.astype(int), submitted.astype(int), verdict.tolerance
        count = int(
            np.any((sub < np.minimum(ref, whole_far) - tol) | (sub > np.maximum(ref, whole_far) + tol), axis=2).sum()
        )
        assert least is not None and least <= count
        assert outside is None or outside == count / (ref.shape[0] * ref.shape[1])
        # and what the first look gives is a lower bound of what the whole grade counts
        for v, variant in graded_by.items():
            least = looks.off_at_least(v, submitted, verdict, looked)
            g = grade(variant, submitted, "", verdict.tolerance)
            assert least is not None and least <= round(g.fraction_off_nearby * reference.shape[0] * reference.shape[1])
    assert spared > 2 * len(submissions)


def test_a_first_look_counts_off_pixels_as_the_grade_does():
    """Both ways: the submitted rows above and below a middle row count too (a reference pixel nothing around it
    matches is off), as the grade counts them."""
    from service.diagnosis.looks import _off_nearby
    from service.images.grading import nearby_difference

    rng = np.random.default_rng(3)
    for _ in range(20):
        bands = rng.integers(0, 256, (5, 3, 17, 3), dtype=np.uint8)
        subs = np.clip(bands.astype(int) + rng.integers(-12, 13, (5, 3, 17, 3)), 0, 255).astype(np.uint8)
        tolerance = float(rng.integers(0, 10))
        alone = sum(
            int(np.count_nonzero(nearby_difference(band, sub, 1, 2) > tolerance)) for band, sub in zip(bands, subs)
        )
        assert _off_nearby(bands, subs, tolerance) == alone


def test_a_first_look_where_the_submission_is_off_rules_out_a_variant_that_leaves_those_rows_alone(setting):
    from service.diagnosis.looks import off_at_least, off_rows, sampled_rows, telling_middles

    scene, reference, _ = setting
    submitted = Renderer(scene, VARIANTS["no-shadows"][0]).pixels()
    verdict = grade(reference, submitted, "")
    pixels = reference.shape[0] * reference.shape[1]
    counts = off_rows(reference, submitted, verdict.tolerance)
    assert not verdict.passed and counts[0] == counts[-1] == 0
    assert 0 < counts.sum() <= round(verdict.fraction_off_nearby * pixels)
    enough = 2 * verdict.max_fraction * pixels
    first = telling_middles(counts, enough)
    assert len(set(first.tolist())) == len(first) <= len(sampled_rows(reference.shape[0])[0])
    assert counts[first].sum() > enough or len(first) == len(sampled_rows(reference.shape[0])[0])
    assert counts[first].min() >= np.sort(counts)[::-1][len(first) - 1]  # (the most off rows)

    def cannot_pass(off: int) -> bool:
        return off / pixels > verdict.max_fraction

    # a variant that leaves the rows as the reference has them: off there as often as the reference, in one look
    unchanged = renders_of(scene)
    unchanged.rows = lambda name, rows: reference[rows]
    assert off_at_least("no-ambient", submitted, verdict, unchanged, cannot_pass, first) == counts[first].sum()
    # and for real variants, the look is still a lower bound of what the whole grade counts
    for v in ("no-shadows", "blinn-phong", "no-ambient"):
        least = off_at_least(v, submitted, verdict, renders_of(scene), None, first)
        g = grade(Renderer(scene, VARIANTS[v][0]).pixels(), submitted, "", verdict.tolerance)
        assert least is not None and least <= round(g.fraction_off_nearby * pixels), v


def test_where_renders_the_failing_pixels_alone_as_the_whole_pass_render_has_them(setting):
    scene, reference, _ = setting
    renders = renders_of(scene)
    student = reference.copy()
    student[5:9, 20:60] = 0
    verdict = grade(reference, student, "")
    rendered = []
    at = renders.at
    renders.at = lambda pixels, fold: rendered.append(len(pixels)) or at(pixels, fold)
    found = diagnosis_where(reference, student, verdict, renders)
    whole = diagnosis_where(reference, student, verdict, WholeImages(renders))
    failing = np.abs(reference.astype(int) - student.astype(int)).max(axis=2) > verdict.tolerance
    assert found == whole and found[0] and rendered == [int(failing.sum())] and 0 < rendered[0] <= 4 * 40


def test_a_variant_rendered_in_bands_is_its_whole_render_or_given_up_only_when_it_cannot_pass(setting):
    from service.diagnosis.looks import whole_unless_off

    scene, reference, _ = setting
    submitted = Renderer(scene, VARIANTS["no-shadows"][0]).pixels()
    verdict = grade(reference, submitted, "")
    pixels = reference.shape[0] * reference.shape[1]
    given_up = 0
    for name in ("no-shadows", "blinn-phong", "no-ambient", "image-flipped", "no-half-pixel"):
        whole = Renderer(scene, VARIANTS[name][0]).pixels()
        off = round(grade(whole, submitted, "", verdict.tolerance).fraction_off_nearby * pixels)
        for enough in (0, 50, off, None):
            beyond = None if enough is None else (lambda count, enough=enough: count > enough)
            banded = whole_unless_off(name, submitted, verdict, renders_of(scene), beyond)
            if banded is None:
                assert enough is not None and off > enough, (name, enough)
                given_up += 1
            else:
                assert np.array_equal(banded, whole), (name, enough)
    assert given_up >= 3


def test_a_diagnosis_holds_no_prepared_scene_once_it_is_over(setting):
    import gc

    scene, reference, _ = setting
    renders = renders_of(scene)
    student = Renderer(scene, VARIANTS["no-ambient"][0]).pixels()
    gc.collect()
    before = sum(isinstance(o, Renderer) for o in gc.get_objects())
    assert diagnose(reference, student, grade(reference, student, ""), renders).causes
    gc.collect()
    assert sum(isinstance(o, Renderer) for o in gc.get_objects()) == before


def _boundary_case():
    """A submission off against the no-shadows variant at exactly a max_fraction of its pixels, 27 of 3000, where
    0.009 × 3000 is 26.999999999999996 in floating point: it passes against that variant, as the grade says.  Its
    off pixels are 90 levels brighter, off but not grossly off (which a rule of its own counts)."""
    from bench.scenes import example

    scene = schemas.validate_scene(example("01_three_spheres", 100, 30))
    variant = Renderer(scene, VARIANTS["no-shadows"][0]).pixels()
    submitted = variant.copy()
    off = 0
    for r in (1, 3, 5, 12, 15, 18, 28):
        for c in range(2, 98, 7):
            if off == 27:
                break
            submitted[r, c] = np.minimum(variant[r, c].astype(int) + 90, 255)
            off = round(grade(variant, submitted, "", 2.0, 0.009).fraction_off_nearby * 3000)
    return scene, Renderer(scene).pixels(), submitted


def test_a_variant_passed_against_at_exactly_the_allowed_share_is_named(monkeypatch):
    scene, reference, submitted = _boundary_case()
    verdict = grade(reference, submitted, "", 2.0, 0.009)
    assert (
        not verdict.passed
        and grade(Renderer(scene, VARIANTS["no-shadows"][0]).pixels(), submitted, "", 2.0, 0.009).passed
    )
    found = diagnose(reference, submitted, verdict, renders_of(scene))
    assert (
        found.as_dict()
        == _blindly(reference, submitted, verdict, WholeImages(renders_of(scene)), monkeypatch).as_dict()
    )
    assert found.causes[0].variant == "no-shadows" and found.causes[0].passes


def test_a_mistake_the_scene_cannot_show_is_never_named_even_against_a_foreign_reference():
    # a reference that is not phongray's render of the scene: the mistakes the scene cannot show (no area light,
    # no spot, no glass) render as phongray's own image, which the student's is; they are no evidence
    from bench.scenes import example

    scene = schemas.validate_scene(example("01_three_spheres", 40, 30))
    ours = Renderer(scene).pixels()
    foreign = ours.copy()
    foreign[5:20, 5:30] = np.clip(foreign[5:20, 5:30].astype(int) + 6, 0, 255).astype(np.uint8)
    verdict = grade(foreign, ours, "")
    assert not verdict.passed
    found = diagnose(foreign, ours, verdict, renders_of(scene))
    from tracer.scene.shown import unchanged

    assert not any(unchanged(c.variant, scene) for c in found.causes)


def test_two_diagnoses_of_one_scene_share_its_rows_safely():
    import threading

    from bench.scenes import example

    scene = schemas.validate_scene(example("01_three_spheres", 20, 12))
    renders = renders_of(scene, threads=1)
    name = "no-shadows"
    renders.rows(name, np.array([0, 1, 2]))  # a first look: rows 0..2 kept
    real = Renderer.pixels_of_rows
    b_rendering, a_done = threading.Event(), threading.Event()

    def slow_for_b(self, rows, **kw):  # B's band (rows 1..4) comes after A has made the whole image
        out = real(self, rows, **kw)
        if threading.current_thread().name == "B":
            b_rendering.set()
            a_done.wait(10)
        return out

    got, errors = {}, {}

    def b():
        try:
            got["B"] = renders.rows(name, np.array([1, 2, 3, 4]))
        except Exception as e:  # noqa: BLE001 (the test reports what went wrong)
            errors["B"] = repr(e)

    def a():
        b_rendering.wait(10)
        got["A"] = renders.variant(name)
        a_done.set()

    Renderer.pixels_of_rows = slow_for_b
    try:
        tb, ta = threading.Thread(target=b, name="B"), threading.Thread(target=a, name="A")
        tb.start(), ta.start()
        tb.join(), ta.join()
    finally:
        Renderer.pixels_of_rows = real
    whole = Renderer(scene, VARIANTS[name][0]).pixels()
    assert not errors and np.array_equal(got["A"], whole) and np.array_equal(got["B"], whole[1:5])


def test_two_diagnoses_of_one_cached_scene_stop_each_on_its_own_cancel():
    import threading

    from bench.scenes import example
    from service.diagnosis import CACHE
    from service.work.pipeline import Checking, Graded, explain
    from tracer import RenderCancelled

    scene = schemas.validate_scene(example("01_three_spheres", 40, 30))
    reference = Renderer(scene).pixels()
    submitted = Renderer(scene, VARIANTS["no-shadows"][0]).pixels()
    verdict = grade(reference, submitted, "")
    CACHE.held.clear()
    both = threading.Barrier(2)
    results = {}

    def run(name, cancel):
        both.wait()
        try:
            found = explain(scene, Graded(verdict, None), reference, submitted, run=Checking(1, cancel)).diagnosis
            results[name] = None if found is None else found.as_dict()
        except RenderCancelled:
            results[name] = "cancelled"

    threads = [
        threading.Thread(target=run, args=("stopped", lambda: True)),
        threading.Thread(target=run, args=("going on", lambda: False)),
    ]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    CACHE.held.clear()
    assert results["stopped"] == "cancelled"
    assert results["going on"]["causes"][0]["variant"] == "no-shadows"


def test_acnes_far_end_in_bands_is_whole_or_given_up_only_when_too_much_lies_outside(setting):
    from service.diagnosis.looks import bound_unless_outside

    scene, reference, _ = setting
    whole = Renderer(scene, BOUNDS["shadow-acne"]).pixels()
    given_up = 0
    for name in ("no-shadows", "no-ambient", "blinn-phong"):
        submitted = Renderer(scene, VARIANTS[name][0]).pixels()
        verdict = grade(reference, submitted, "")
        ref, far, sub = (a.astype(int) for a in (reference, whole, submitted))
        tol = verdict.tolerance
        outside = int(np.any((sub < np.minimum(ref, far) - tol) | (sub > np.maximum(ref, far) + tol), axis=2).sum())
        for enough in (0, 40, outside, None):
            beyond = None if enough is None else (lambda count, enough=enough: count > enough)
            banded = bound_unless_outside("shadow-acne", reference, submitted, verdict, renders_of(scene), beyond)
            if banded is None:
                assert enough is not None and outside > enough, (name, enough)
                given_up += 1
            else:
                assert np.array_equal(banded, whole), (name, enough)
    assert given_up >= 3


def test_a_diagnosis_read_back_from_its_json_is_the_same_record_with_the_same_words():
    from service.diagnosis import Cause, Diagnosis, Share, Term, headline, unavailable

    found = Diagnosis(
        causes=[Cause("no-shadows", "no shadow rays", 0.3, False)],
        closest=True,
        terms=[Term("diffuse", 1, 0.02)],
        objects=[Share(0, "sphere", 0.75), Share(-1, "background", 0.25)],
        lights=[Share(1, "point", 0.5)],
    )
    assert Diagnosis.from_dict(found.as_dict()) == found
    assert headline(found) == "no shadow rays (closest)" and headline(None) == ""
    termed = Diagnosis(terms=[Term("diffuse", 1, 0.02)])
    assert termed.headline() == "the diffuse of lights[1] is missing"  # (a record without its scene's words)
    assert termed.sentence() == "Likely: the diffuse of lights[1] is missing"
    worded = Diagnosis(terms=[Term("diffuse", 1, 2.02, 0.7, "the diffuse of light 'key' is twice as bright")])
    assert worded.sentence() == "Likely: the diffuse of light 'key' is twice as bright"
    assert Diagnosis.from_dict(worded.as_dict()) == worded
    nearest = Diagnosis(
        causes=[
            Cause(
                "term:diffuse:1",
                "the diffuse of light 'key', which is missing",
                0.5,
                False,
                [],
                0.8,
                "accounts for about 80 % of the difference",
            )
        ]
    )
    assert nearest.nearest and nearest.sentence() == (
        "No known mistake fits exactly: most of the difference is the "
        "diffuse of light 'key', which is missing (about 80 %)"
    )
    assert Diagnosis.from_dict(nearest.as_dict()) == nearest
    both = Diagnosis(
        causes=[
            Cause("no-shadows", "no shadow rays", 0.0, True, ["gamma"], 0.6, "e"),
            Cause("gamma", "gamma", 0.0, True, ["no-shadows"], 0.4, "e"),
        ]
    )
    assert both.together and both.headline() == "no shadow rays + gamma"
    assert both.sentence().startswith("Likely two mistakes together: no shadow rays and gamma")
    assert Diagnosis.from_dict(both.as_dict()) == both
    assert Diagnosis().headline() == "no known mistake fits"
    late = unavailable("every render slot is busy")
    assert late.as_dict() == {
        "sentence": "No diagnosis: every render slot is busy",
        "closest": False,
        "causes": [],
        "terms": [],
        "objects": [],
        "lights": [],
    }
    assert Diagnosis.from_dict(late.as_dict()) == late and late.headline() == late.sentence()


@pytest.mark.parametrize(
    "scene_name, mistake",
    [
        ("07_spotlights", "spot-cone-ignored"),
        ("02_all_lights", "spot-cone-ignored"),
        ("02_all_lights", "attenuation-not-squared"),
        ("02_all_lights", "shadow-past-light"),
        ("02_all_lights", "specular-in-shadow"),
        ("07_spotlights", "specular-in-shadow"),
    ],
)
def test_a_spot_lit_as_a_point_light_or_a_distance_not_squared_is_named(scene_name, mistake):
    """Mistakes students' tracers written from the format alone showed unnamed (the cause blamed the ambient
    term, or another light): a spot lit as a point light, attenuation's q·d for q·d², a shadow ray not stopped
    at its light (what lies beyond a lamp shadows what it lights), a shadow test that skips the specular term
    (highlights shine in shadow).  Made by the
    object-oriented student, each is named and matched."""
    import student_oop
    from test_compose import small

    scene = small(scene_name, 96, 72)
    reference = Renderer(scene).pixels()
    made = student_oop.render(scene, [mistake])
    verdict = grade(reference, made, "")
    assert not verdict.passed
    found = diagnose(reference, made, verdict, renders_of(scene))
    assert found.causes[0].variant == mistake and found.causes[0].passes and not found.closest


def test_a_mistake_that_explains_little_of_the_difference_is_not_named_as_the_nearest():
    """A student's spot cone drawn too narrow was told 'some of the difference is what the image saved in
    grayscale changes (about 40 %)': a mistake they did not make.  Below most of the difference a mistake is not
    named; the sentence says where the difference lies instead.  One that explains most of it still is."""
    from service.diagnosis import Cause, Diagnosis, Share

    def near(share: float) -> Diagnosis:
        cause = Cause("grayscale", "what the image saved in grayscale changes", 0.3, False, [], share, "")
        objects = [Share(0, "plane", 0.8, "the first plane"), Share(1, "sphere", 0.2, "the first sphere")]
        lights = [Share(2, "spot", 0.9, "the third light (spot)"), Share(1, "point", 0.1, "the second light (point)")]
        return Diagnosis(causes=[cause], objects=objects, lights=lights)

    little = near(0.4)
    assert little.nearest and little.sentence() == (
        "No known mistake fits: compare the heat-map with the reference; the difference is mostly on the first "
        "plane, in the light of the third light (spot)"
    )
    assert little.headline() == "no known mistake fits"
    little.lights = little.lights[:1]  # (the one light on every failing pixel tells nothing of the mistake)
    assert little.sentence().endswith("the difference is mostly on the first plane")
    most = near(0.7)
    assert most.sentence().startswith("No known mistake fits exactly: most of the difference is what the image")
    assert most.headline() == "nearest: what the image saved in grayscale changes"


def test_speckles_only_on_the_references_edges_are_not_acnes():
    """A student who averages sub-samples in gamma space differs only where a pixel mixes two surfaces: 0.84 %
    of the Cornell homework, darker, and between the reference and acne's far end, so acne's test passed it and
    'shadow acne' was named.  Departures are speckles only where enough of them go beyond every reference pixel
    around them; the same speckles on a surface's inside are acne's still."""
    from service.diagnosis.looks import speckled

    reference = np.full((40, 40, 3), 200, dtype=np.uint8)
    reference[:, 20:] = 60  # (two surfaces, one edge between them)
    far = np.full_like(reference, 20)  # (acne's far end: every lit point in shadow)
    rows = np.arange(0, 40, 2)
    on_edge = reference.copy()
    on_edge[rows, 19] = 120  # (the edge's pixels, every other one darker: speckled along it)
    assert speckled(reference, far, on_edge, 2.0) is None
    inside = reference.copy()
    inside[rows, 8] = 120  # (the same speckles inside the bright surface)
    assert speckled(reference, far, inside, 2.0) == 0.0
