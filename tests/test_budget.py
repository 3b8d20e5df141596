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
    return {
        "camera": {"position": [0, 0, 0.5], "look_at": [0, 0, 0]},
        "image": {"width": size, "height": size},
        "materials": {"m": {}},
        "objects": objs,
        "lights": [{"type": "point", "color": 1, "position": [0.2, 0.2, 0.2]}],
    }


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
    out = subprocess.run(
        [sys.executable, "-c", PEAK_SCRIPT],
        input=json.dumps(around_the_eye(10_000, 32)),
        capture_output=True,
        text=True,
        check=True,
        timeout=600,
    )
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


def test_a_render_past_its_budget_of_exact_tests_stops_naming_them():
    """Spheres far larger than the rest are tested against every ray: the tests are counted, whatever the rays."""
    objs = [{"type": "sphere", "material": "m", "center": [k * 0.01, 0, 0], "radius": 0.001} for k in range(40)]
    objs += [{"type": "sphere", "material": "m", "center": [0, 0, -1000 - k], "radius": 500.0} for k in range(39)]
    scene = schemas.validate_scene(
        {
            "camera": {"position": [0, 0, 30], "look_at": [0, 0, 0]},
            "image": {"width": 32, "height": 32},
            "materials": {"m": {}},
            "objects": objs,
            "lights": [{"type": "point", "color": 1, "position": [0, 50, 0]}],
        }
    )
    whole = Renderer(scene)
    whole.pixels(threads=1)
    assert whole.tests >= 32 * 32 * 39
    renderer = Renderer(scene)
    with pytest.raises(OverBudget) as stopped:
        renderer.pixels(threads=1, budget=Budget(tests=whole.tests / 2))
    assert stopped.value.what == "tests"


def test_the_foresight_sees_the_chunks_not_begun():
    """Many chunks, each a small share of the budget, that make a render far over it: each chunk's own tree
    foresees little, so the foresight also extends what the chunks begun spend per camera ray to those not
    begun (nested glass at depth 12 and 1024² ran into the service's render_timeout on a loaded machine)."""
    scene = schemas.validate_scene(nested_glass_and_mirror(8, 64))
    whole = Renderer(scene)
    whole.pixels(threads=1, chunk_rays=256)
    renderer = Renderer(scene)
    with pytest.raises(OverBudget) as stopped:
        renderer.pixels(threads=1, chunk_rays=256, budget=Budget(rays=whole.spent / 20))
    assert stopped.value.foreseen
    assert renderer.spent < whole.spent / 20 / 2


def test_a_budget_it_stays_within_foresees_no_more_than_it_spends():
    """The tightest budget an honest render fits (its own count) does not stop it: what the chunks begun spend
    per camera ray, extended to the rest, stays within FORESIGHT times the budget."""
    scene = schemas.validate_scene(nested_glass_and_mirror(8, 48))
    whole = Renderer(scene)
    image = whole.pixels(threads=2, chunk_rays=64)
    again = Renderer(scene).pixels(threads=2, chunk_rays=64, budget=Budget(rays=whole.spent))
    assert np.array_equal(image, again)


WIDE_SCRIPT = """
import json, sys
import schemas
from tracer import Renderer
renderer = Renderer(schemas.validate_scene(json.loads(sys.stdin.read())))
renderer.camera.rays(0, 4096)
renderer.camera.rays(16777216 - 4096, 16777216)
print(next(int(l.split()[1]) for l in open("/proc/self/status") if l.startswith("VmHWM:")) // 1024)
"""


@pytest.mark.parametrize("size", [(16777216, 1), (1, 16777216)])
def test_an_image_of_one_row_or_column_holds_no_table_of_its_size(size):
    """16777216 × 1 pixels (within max_pixels = 4096²) with 2×2 samples: the camera's per-column tables took
    800 MiB before the first ray, and a render peaked at 1.4 GiB; the columns of each batch are made instead."""
    data = {
        "camera": {"position": [0, 0, 5], "look_at": [0, 0, 0]},
        "image": {"width": size[0], "height": size[1], "samples": 2},
        "materials": {"m": {}},
        "objects": [{"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 1}],
        "lights": [{"type": "point", "color": 1, "position": [2, 2, 2]}],
    }
    out = subprocess.run(
        [sys.executable, "-c", WIDE_SCRIPT], input=json.dumps(data), capture_output=True, text=True, timeout=300
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert int(out.stdout) < 400


@pytest.mark.parametrize("name", ["08_antialiased", "06_orthographic"])
def test_the_camera_rays_are_the_same_made_per_batch(name, monkeypatch):
    from tracer.scene import camera

    scene = schemas.validate_scene(scene_dict(name))
    tabled = Renderer(scene).pixels(threads=2, chunk_rays=5000)
    monkeypatch.setattr(camera, "TABLE_MAX", 0)
    assert np.array_equal(Renderer(scene).pixels(threads=2, chunk_rays=5000), tabled)


@pytest.mark.parametrize("look", [-2.0, -2.3, -2.6])
def test_a_render_whose_work_lies_in_its_first_rows_is_not_stopped_within_its_budget(look):
    """Nested glass in the top 4 to 13 rows of 64, one row a chunk: the first chunks, extended to the rest,
    foresaw 5 to 9 times what the render spends, and stopped it at its own count."""
    data = nested_glass_and_mirror(8, 64)
    data["camera"]["look_at"] = [0, look, 0]
    scene = schemas.validate_scene(data)
    whole = Renderer(scene)
    image = whole.pixels(threads=1, chunk_rays=64)
    assert np.array_equal(Renderer(scene).pixels(threads=1, chunk_rays=64, budget=Budget(rays=whole.spent)), image)
