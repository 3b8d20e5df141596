"""Property-based tests over the scene format: accepted scenes render, rejected ones say where."""

import json
import os

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import schemas
from tracer import ImageTooLarge, Renderer

from helpers import EXAMPLES, scene_dict

#: examples per property; raise it for a longer hunt: PHONGRAY_PROPERTY_EXAMPLES=5000 pytest tests/test_properties.py
EXAMPLES_PER_TEST = int(os.environ.get("PHONGRAY_PROPERTY_EXAMPLES", "200"))
EXTREMES = [0.0, 1e-300, -1e-300, 1e300, -1e300, 1e6, -1e6, 1e-9, 1.0, -1.0]
num = st.one_of(st.floats(-50, 50, allow_nan=False), st.sampled_from(EXTREMES))
positive = st.one_of(st.floats(1e-3, 20), st.sampled_from([1e-300, 1e-9, 1e9, 1e300]))
vec = st.lists(num, min_size=3, max_size=3)
unit_interval = st.floats(0, 1)
colour = st.one_of(st.floats(0, 3), st.lists(st.floats(0, 3), min_size=3, max_size=3), st.sampled_from([1e300]))
attenuation = st.one_of(
    st.just([1, 0, 0]), st.lists(st.sampled_from([0.0, 0.5, 1.0, 1e-300, 1e300]), min_size=3, max_size=3)
)

material = st.fixed_dictionaries(
    {},
    optional={
        "ambient": colour,
        "diffuse": colour,
        "specular": colour,
        "shininess": st.sampled_from([0, 1, 10, 200, 1e6]),
        "reflectance": unit_interval,
        "transmittance": unit_interval,
        "ior": st.sampled_from([0.5, 1.0, 1.5, 3.0]),
    },
)

sphere = st.fixed_dictionaries({"type": st.just("sphere"), "material": st.just("a"), "center": vec, "radius": positive})
plane = st.fixed_dictionaries({"type": st.just("plane"), "material": st.just("b"), "point": vec, "normal": vec})
triangle = st.fixed_dictionaries(
    {"type": st.just("triangle"), "material": st.just("a"), "vertices": st.lists(vec, min_size=3, max_size=3)}
)
mesh = st.integers(3, 6).flatmap(
    lambda n: st.fixed_dictionaries(
        {
            "type": st.just("mesh"),
            "material": st.just("b"),
            "vertices": st.lists(vec, min_size=n, max_size=n),
            "faces": st.lists(st.lists(st.integers(0, n - 1), min_size=3, max_size=3), min_size=1, max_size=4),
        },
        optional={"normals": st.lists(vec, min_size=n, max_size=n)},
    )
)

light = st.one_of(
    st.fixed_dictionaries({"type": st.just("ambient"), "color": colour}),
    st.fixed_dictionaries({"type": st.just("directional"), "color": colour, "direction": vec}),
    st.fixed_dictionaries({"type": st.just("point"), "color": colour, "position": vec, "attenuation": attenuation}),
    st.fixed_dictionaries(
        {
            "type": st.just("spot"),
            "color": colour,
            "position": vec,
            "direction": vec,
            "attenuation": attenuation,
            "cutoff": st.sampled_from([1, 30, 89.9, 90]),
            "inner_cutoff": st.sampled_from([0.5, 1, 30]),
            "exponent": st.sampled_from([0, 1, 50]),
        }
    ),
    st.fixed_dictionaries(
        {
            "type": st.just("area"),
            "color": colour,
            "corner": vec,
            "edge_u": vec,
            "edge_v": vec,
            "samples": st.lists(st.integers(1, 3), min_size=2, max_size=2),
        }
    ),
)

scene = st.fixed_dictionaries(
    {
        "camera": st.fixed_dictionaries(
            {"position": vec, "look_at": vec},
            optional={
                "type": st.sampled_from(["perspective", "orthographic"]),
                "up": vec,
                "fov": st.floats(0.5, 179.5),
                "height": positive,
            },
        ),
        "image": st.fixed_dictionaries(
            {"width": st.integers(1, 5), "height": st.integers(1, 5)},
            optional={"samples": st.integers(1, 2), "max_depth": st.integers(0, 3), "background": colour},
        ),
        "materials": st.fixed_dictionaries({"a": material, "b": material}),
        "objects": st.lists(st.one_of(sphere, plane, triangle, mesh), max_size=4),
        "lights": st.lists(light, max_size=3),
    }
)


def render_or_problems(data):
    """Either the linear colour of every pixel of an accepted scene, or the problems of a rejected one."""
    try:
        accepted = schemas.validate_scene(data)
    except schemas.SceneError as exc:
        return None, exc.problems
    img = accepted.image
    if img.width * img.height * img.samples**2 > 100_000:  # beyond a unit test's budget: valid, not rendered
        return np.zeros((1, 3)), None
    try:
        renderer = Renderer(accepted)
    except ImageTooLarge as exc:  # valid, but more than phongray renders (an area light of 8×135662 samples):
        assert str(exc).split(":")[0] in ("image", "lights"), exc  # refused, naming what is too large
        return np.zeros((1, 3)), None
    return renderer.chunk(0, img.width * img.height), None


@settings(max_examples=EXAMPLES_PER_TEST, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scene)
def test_accepted_scenes_render_finite_pixels_and_rejected_ones_are_located(data):
    colour, problems = render_or_problems(data)
    if problems is None:
        assert not np.any(np.isnan(colour)), json.dumps(data)  # the scene, to reproduce a failure
        img = Renderer(schemas.validate_scene(data)).pixels(threads=1)
        assert img.shape == (data["image"]["height"], data["image"]["width"], 3)
    else:
        assert problems and all(path and message for path, message in problems)


json_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(10**20), 10**20)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=8),
    lambda children: st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=8), children, max_size=4),
    max_leaves=20,
)


@settings(max_examples=EXAMPLES_PER_TEST, deadline=None)
@given(json_values)
def test_any_json_document_is_a_scene_or_a_located_error(value):
    try:
        schemas.load_scene(json.dumps(value))
    except schemas.SceneError as exc:
        assert exc.problems and all(message for _, message in exc.problems)


def leaf_paths(value, path=()):
    if isinstance(value, dict):
        for key, child in value.items():
            yield from leaf_paths(child, (*path, key))
    elif isinstance(value, list) and value:
        for i, child in enumerate(value):
            yield from leaf_paths(child, (*path, i))
    yield path


@settings(max_examples=EXAMPLES_PER_TEST, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(EXAMPLES), st.data())
def test_a_mutated_example_renders_or_names_the_mutated_place(name, data):
    doc = scene_dict(name)
    doc["image"].update(width=4, height=3, samples=1)
    paths = [p for p in leaf_paths(doc) if p]
    path = data.draw(st.sampled_from(paths))
    replacement = data.draw(json_values)
    parent = doc
    for key in path[:-1]:
        parent = parent[key]
    parent[path[-1]] = replacement
    colour, problems = render_or_problems(doc)
    if problems is None:
        assert not np.any(np.isnan(colour)), json.dumps(doc)
    else:
        assert all(message for _, message in problems)
        assert any(p for p, _ in problems) or path[0] not in ("camera", "image")
