"""A render's budget, counted while it runs (tracer/budget.py): rays traced and memory held, and the walk's
pairs made a group at a time so that many primitives around the eye hold bounded memory."""

import json
import subprocess
import sys

import numpy as np
import pytest
from test_render import nested_glass_and_mirror

import schemas
from tracer import Budget, OverBudget, Renderer, encode_png

from helpers import scene_dict


def around_the_eye(count, size):
    """``count`` concentric spheres, the camera inside them all: every camera ray crosses every sphere."""
    objs = [{"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 1.0 + k} for k in range(count)]
    return {"camera": {"position": [0, 0, 0.5], "look_at": [0, 0, 0]}, "image": {"width": size, "height": size},
            "materials": {"m": {}}, "objects": objs,
            "lights": [{"type": "point", "color": 1, "position": [0.2, 0.2, 0.2]}]}


def test_a_render_past_its_ray_budget_stops_naming_the_rays():
    scene = schemas.validate_scene(scene_dict("04_whitted"))
    whole = Renderer(scene)
    whole.pixels(threads=2, chunk_rays=4096)
    renderer = Renderer(scene)
    with pytest.raises(OverBudget) as stopped:
        renderer.pixels(threads=2, chunk_rays=4096, budget=Budget(rays=whole.spent / 2))
    assert stopped.value.what == "rays" and not stopped.value.foreseen
    assert whole.spent / 2 < renderer.spent < whole.spent


def test_a_ray_tree_far_over_its_budget_is_stopped_by_foresight_long_before_it_is_spent():
    """Nested glass and mirrors at depth 16: 2^17 rays per camera ray.  Depth-first, the first slice of each
    depth shows the rate at which the tree grows: the render stops having spent a fraction of its budget."""
    renderer = Renderer(schemas.validate_scene(nested_glass_and_mirror(16, 32)))
    with pytest.raises(OverBudget) as stopped:
        renderer.pixels(threads=2, chunk_rays=4096, budget=Budget(rays=1_000_000))
    assert stopped.value.what == "rays" and stopped.value.foreseen and stopped.value.spent > 4_000_000
    assert renderer.spent < 1_000_000


def test_a_render_past_its_memory_budget_stops_naming_the_memory():
    renderer = Renderer(schemas.validate_scene(nested_glass_and_mirror(12, 64)))
    with pytest.raises(OverBudget) as stopped:
        renderer.pixels(threads=1, chunk_rays=1024, budget=Budget(ray_bytes=200_000))
    assert stopped.value.what == "memory" and stopped.value.spent > 200_000


@pytest.mark.parametrize("name", ["04_whitted", "03_soft_shadows"])
def test_a_budget_it_stays_within_changes_no_byte(name):
    scene = schemas.validate_scene(scene_dict(name))
    plain = Renderer(scene)
    first = encode_png(plain.pixels(threads=2))
    budgeted = Renderer(scene)
    assert encode_png(budgeted.pixels(threads=2, budget=Budget(rays=plain.spent, ray_bytes=1 << 30))) == first
    assert budgeted.spent == plain.spent


def test_the_count_starts_again_with_each_render():
    renderer = Renderer(schemas.validate_scene(nested_glass_and_mirror(3, 16)))
    renderer.pixels(threads=1)
    spent = renderer.spent
    renderer.pixels(threads=1, budget=Budget(rays=spent))  # the first render's rays are not counted again


PEAK_SCRIPT = """
import json, sys
import schemas, tracer
tracer.render(schemas.validate_scene(json.loads(sys.stdin.read())), threads=2)
print(next(int(l.split()[1]) for l in open("/proc/self/status") if l.startswith("VmHWM:")) // 1024)
"""


def test_ten_thousand_spheres_around_the_eye_hold_bounded_memory():
    """Every camera ray meets all 10,000 spheres in every cell it crosses: made into pairs at once, 32² rays
    peaked at 710 MiB (96²: 5.2 GiB); a group at a time, 155 MiB."""
    out = subprocess.run([sys.executable, "-c", PEAK_SCRIPT], input=json.dumps(around_the_eye(10_000, 32)),
                         capture_output=True, text=True, check=True, timeout=600)
    assert int(out.stdout) < 400  # MiB


def test_a_budget_applies_to_its_own_render_only():
    """A renderer stopped by one render's budget renders rows afterwards with no budget of its own."""
    renderer = Renderer(schemas.validate_scene(scene_dict("04_whitted")))
    with pytest.raises(OverBudget):
        renderer.pixels(threads=1, budget=Budget(rays=10))
    rows = renderer.pixels_of_rows(np.arange(3), threads=1)
    assert np.array_equal(rows, Renderer(renderer.scene).pixels(threads=1)[:3])


def test_a_huge_max_depth_costs_no_memory_of_its_own():
    """Run locally, a scene is trusted, max_depth 10^9 included: the foresight's tally grows with the depths the
    tree reaches, not with max_depth (a list of 10^9 counts would take 8 GB)."""
    data = scene_dict("04_whitted")
    data["image"].update(width=32, height=24)
    shallow = Renderer(schemas.validate_scene(data)).pixels(threads=1)
    data["image"]["max_depth"] = 10**9
    deep = Renderer(schemas.validate_scene(data))
    assert deep.pixels(threads=1, budget=Budget(rays=1e9)).shape == shallow.shape
