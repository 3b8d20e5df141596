"""Shadow rays (tracer/shade/shadows.py): queries decided together answer as each decided alone, and an area
light's samples, and a run of point, spot and directional lights, cost one occlusion query per shading step, not
one per sample or light."""

import numpy as np
import pytest

import schemas
from tracer import Renderer
from tracer.exact.intersect import Intersector
from tracer.scene.variants import REFERENCE, Options
from tracer.shade import area, direct
from tracer.shade.shadows import Query, ShadowRays

VARIANTS = {
    "reference": REFERENCE,
    "offset-normal": Options(offset=0.002),
    "offset-ray": Options(offset=0.002, offset_along="ray"),
    "acne": Options(acne=True),
    "glass-casts-none": Options(transparent_shadows=False),
    "lit-from-behind": Options(specular_behind=True),  # (no penumbra: each sample's pairs from the cones, or none)
}


def scene(
    spheres: int, seed: int = 0, samples: int = 4, depth: int = 2, point: bool = True, more: tuple[dict, ...] = ()
) -> schemas.Scene:
    """Spheres (some glass) over a floor, a small mesh, an area light of ``samples``² samples and a point light
    (with ``point``), and the lights ``more``."""
    rng = np.random.default_rng(seed)
    objects = [
        {
            "type": "sphere",
            "material": "glass" if k % 3 == 0 else "m",
            "center": [float(rng.uniform(-2, 2)), float(rng.uniform(-0.5, 1.5)), float(rng.uniform(-2, 1))],
            "radius": float(rng.uniform(0.15, 0.6)),
        }
        for k in range(spheres)
    ]
    objects.append({"type": "plane", "material": "m", "point": [0, -1, 0], "normal": [0, 1, 0]})
    objects.append(
        {
            "type": "mesh",
            "material": "m",
            "vertices": [[-1.5, -1, -1], [-0.5, -1, -1], [-1, 0.2, -1.4], [-1, -1, -0.3]],
            "faces": [[0, 1, 2], [1, 3, 2], [3, 0, 2]],
        }
    )
    return schemas.validate_scene(
        {
            "camera": {"position": [0, 1.5, 6], "look_at": [0, 0, 0], "fov": 50},
            "image": {"width": 40, "height": 30, "samples": 2, "max_depth": depth},
            "materials": {
                "m": {"diffuse": 0.7, "specular": 0.3, "shininess": 20, "reflectance": 0.2},
                "glass": {"diffuse": 0.1, "specular": 0.5, "transmittance": 0.8, "ior": 1.5},
            },
            "objects": objects,
            "lights": [
                {
                    "type": "area",
                    "color": 0.8,
                    "corner": [-1, 3, -1],
                    "edge_u": [2, 0, 0],
                    "edge_v": [0, 0, 2],
                    "samples": [samples, samples],
                },
            ]
            + ([{"type": "point", "color": 0.4, "position": [2, 2.5, 3]}] if point else [])
            + list(more),
        }
    )


@pytest.mark.parametrize("variant", sorted(VARIANTS))
@pytest.mark.parametrize("spheres", [6, 40])  # few surfaces (the cones' pairs) and too many for them (the walk)
def test_queries_decided_together_answer_as_each_alone(monkeypatch, variant, spheres):
    decide = ShadowRays.decide
    joined = []

    def checked(self: ShadowRays, queries: list[Query]) -> list[np.ndarray]:
        together = decide(self, queries)
        alone = [decide(self, [q])[0] for q in queries]
        for a, b in zip(together, alone):
            np.testing.assert_array_equal(a, b)
        joined.append(sum(q.n > 0 for q in queries))
        return together

    monkeypatch.setattr(ShadowRays, "decide", checked)
    renderer = Renderer(scene(spheres), VARIANTS[variant])
    pixels = np.random.default_rng(spheres).choice(40 * 30, 150, replace=False)
    renderer.pixels_at(pixels, threads=1)
    assert max(joined) > 1  # (several samples' rays decided in one query)


def test_every_sample_joined_or_alone_renders_the_same_bytes(monkeypatch):
    pixels = np.random.default_rng(3).choice(40 * 30, 200, replace=False)
    for variant in VARIANTS.values():
        together = Renderer(scene(8, seed=1), variant).pixels_at(pixels, threads=1)
        with monkeypatch.context() as m:
            m.setattr(area, "JOINED_RAYS", 1)  # (a run of one sample: each sample's rays decided alone)
            alone = Renderer(scene(8, seed=1), variant).pixels_at(pixels, threads=1)
        np.testing.assert_array_equal(together, alone)


def counted_queries(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The rays of each occlusion query the renders make from now on, in order."""
    occluded = Intersector.occluded
    calls: list[int] = []

    def counted(self, shadows, among=None):
        calls.append(len(shadows))
        return occluded(self, shadows, among)

    monkeypatch.setattr(Intersector, "occluded", counted)
    return calls


def test_an_area_light_costs_one_occlusion_query_per_shading_step(monkeypatch):
    calls = counted_queries(monkeypatch)
    renderer = Renderer(scene(6, samples=5, depth=0, point=False))  # (the camera rays' hits alone: one step)
    rows = np.arange(10, 20) * 40
    renderer.pixels_at((rows[:, None] + np.arange(40)).ravel(), threads=1)
    assert len(calls) == 1 and calls[0] > 0


#: lights of one emitter each, of both forms of shadow ray (towards a point; along a direction), after the area
#: light and its point light: a run of five whose rays are decided together
SINGLES = (
    {"type": "point", "color": 0.3, "position": [-2, 3, 1]},
    {"type": "directional", "color": 0.2, "direction": [0.3, -1, -0.4]},
    {"type": "spot", "color": 0.5, "position": [1, 3, 2], "direction": [-0.2, -1, -0.5], "cutoff": 35},
    {"type": "point", "color": 0.3, "position": [0.5, 0.3, 2.5]},
    {"type": "directional", "color": 0.2, "direction": [-0.5, -1, 0.2]},
)


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_a_run_of_lights_joined_or_each_alone_renders_the_same_bytes(monkeypatch, variant):
    """Every variant; with pixels of one point each too (a batch of one: its shadow rays' directions are copied
    out of the kernel's (1, 3) buffer, which the next light's reach rewrites before the run is decided)."""
    pixels = np.random.default_rng(5).choice(40 * 30, 200, replace=False)
    made = scene(8, seed=2, samples=2, more=SINGLES)
    made = made.model_copy(update={"image": made.image.model_copy(update={"samples": 1})})  # (a ray a pixel)
    together = Renderer(made, VARIANTS[variant]).pixels_at(pixels, threads=1)
    ones = [Renderer(made, VARIANTS[variant]).pixels_at(pixels[k : k + 1], threads=1) for k in range(0, 200, 4)]
    with monkeypatch.context() as m:
        m.setattr(direct, "JOINED_RAYS", 1)  # (a run of one light: each light's rays decided alone)
        alone = Renderer(made, VARIANTS[variant]).pixels_at(pixels, threads=1)
    np.testing.assert_array_equal(together, alone)
    np.testing.assert_array_equal(np.concatenate(ones), alone[::4])


def test_a_run_of_lights_costs_one_occlusion_query_per_shading_step(monkeypatch):
    calls = counted_queries(monkeypatch)
    lights = tuple(light for light in SINGLES if light["type"] != "directional")  # (one form: at a point)
    renderer = Renderer(scene(6, samples=1, depth=0, point=False, more=lights))
    rows = np.arange(10, 20) * 40
    renderer.pixels_at((rows[:, None] + np.arange(40)).ravel(), threads=1)
    assert len(calls) == 2 and all(calls)  # (the area light's one sample, then the run of three)
