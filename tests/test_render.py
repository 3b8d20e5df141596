"""Whole scenes: the reference images, translation invariance, determinism and hard cases."""

import copy
import gc
import json
import subprocess
import sys
import time
import weakref

import numpy as np
import pytest

import schemas
from tracer import RenderCancelled, Renderer, encode_png

from helpers import EXAMPLES, differing, mean_abs, measured, reference, render_dict, scaled, scene_dict, translated


@pytest.fixture(scope="module")
def renders():
    return {name: render_dict(scene_dict(name)) for name in EXAMPLES}


@pytest.mark.parametrize("name", EXAMPLES)
def test_matches_reference(renders, name):
    img, ref = renders[name], reference(name)
    assert img.shape == ref.shape
    assert differing(img, ref) <= 0.001
    assert mean_abs(img, ref) < 0.1


@pytest.mark.parametrize("name", EXAMPLES)
def test_scene_moved_far_from_the_origin_renders_the_same(renders, name):
    moved = render_dict(translated(scene_dict(name), (1e6, -1e6, 1e6)))
    assert differing(moved, renders[name], tolerance=0) <= 0.001


@pytest.mark.parametrize("name", ["01_three_spheres", "04_whitted", "05_mesh", "06_orthographic"])
@pytest.mark.parametrize("factor", [1e-6, 1e6])
def test_scene_scaled_up_or_down_renders_the_same(renders, name, factor):
    assert differing(render_dict(scaled(scene_dict(name), factor)), renders[name]) <= 0.001


def test_same_bytes_for_any_thread_count_and_chunk_size():
    scene = schemas.validate_scene(scene_dict("04_whitted"))
    first = encode_png(Renderer(scene).pixels(threads=1))
    assert encode_png(Renderer(scene).pixels(threads=2, chunk_rays=999)) == first
    assert encode_png(Renderer(scene).pixels(threads=3, chunk_rays=4096)) == first


def floor_as_triangles(data, size):
    out = copy.deepcopy(data)
    s = size
    out["objects"][0] = {
        "type": "mesh",
        "material": out["objects"][0]["material"],
        "vertices": [[-s, 0, -s], [s, 0, -s], [s, 0, s], [-s, 0, s]],
        "faces": [[0, 2, 1], [0, 3, 2]],
    }
    return out


@pytest.mark.parametrize("size", [1e3, 1e5])
def test_triangle_floor_has_no_acne_and_matches_the_plane(renders, size):
    img = render_dict(floor_as_triangles(scene_dict("01_three_spheres"), size))
    assert differing(img, renders["01_three_spheres"]) <= 0.001


@pytest.mark.parametrize("radius", [1e6, 1e9])
def test_planet_sized_sphere_floor_matches_the_plane(renders, radius):
    data = scene_dict("01_three_spheres")
    data["objects"][0] = {"type": "sphere", "material": "floor", "center": [0, -radius, 0], "radius": radius}
    assert differing(render_dict(data), renders["01_three_spheres"]) <= 0.001


def hard_scene(objects, lights, camera=None, **image):
    return {
        "camera": camera or {"position": [0, 1, 4], "look_at": [0, 0.5, 0]},
        "image": {"width": 48, "height": 36, "max_depth": 3, **image},
        "materials": {
            "m": {"reflectance": 0.3, "transmittance": 0.3},
            "c": {"checker": {"size": 0.25, "material": "m"}},
        },
        "objects": objects,
        "lights": lights,
    }


FLOOR = {"type": "plane", "material": "c", "point": [0, 0, 0], "normal": [0, 1, 0]}
BALL = {"type": "sphere", "material": "m", "center": [0, 0.5, 0], "radius": 0.5}
LAMP = {"type": "point", "color": 1, "position": [1, 3, 2]}

HARD = {
    "camera inside a sphere": hard_scene([FLOOR, {**BALL, "radius": 10}], [LAMP, {"type": "ambient", "color": 0.2}]),
    "light exactly on the floor": hard_scene([FLOOR, BALL], [{**LAMP, "position": [1, 0, 1]}]),
    "light exactly on a sphere": hard_scene([FLOOR, BALL], [{**LAMP, "position": [0, 1, 0]}]),
    "camera in the floor plane": hard_scene(
        [FLOOR, BALL], [LAMP], camera={"position": [0, 0, 4], "look_at": [0, 0, 0]}
    ),
    "coplanar planes and triangle": hard_scene(
        [
            FLOOR,
            {**FLOOR, "material": "m"},
            {"type": "triangle", "material": "m", "vertices": [[-1, 0, -1], [1, 0, -1], [0, 0, 1]]},
            BALL,
        ],
        [LAMP],
    ),
    "tiny sphere on a huge one": hard_scene(
        [
            {"type": "sphere", "material": "c", "center": [0, -1e7, 0], "radius": 1e7},
            {"type": "sphere", "material": "m", "center": [0, 1e-4, 0], "radius": 1e-4},
        ],
        [LAMP],
        camera={"position": [0, 2e-4, 6e-4], "look_at": [0, 1e-4, 0]},
    ),
    "grazing light": hard_scene([FLOOR, BALL], [{"type": "directional", "color": 1, "direction": [1, -1e-9, 0]}]),
    "spot with a 90 degree cone and zero exponent": hard_scene(
        [FLOOR, BALL],
        [
            {
                "type": "spot",
                "color": 1,
                "position": [0, 2, 0],
                "direction": [0, -1, 0],
                "cutoff": 90,
                "exponent": 0,
                "attenuation": [0, 0, 1],
            }
        ],
    ),
    "zero-area mesh faces": hard_scene(
        [
            FLOOR,
            {
                "type": "mesh",
                "material": "m",
                "vertices": [[0, 0, 0], [1, 1, 1], [2, 2, 2], [0, 1, 0]],
                "faces": [[0, 1, 2], [0, 1, 3]],
                "normals": [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, 0, 1]],
            },
        ],
        [LAMP],
    ),
    "reflection weight underflowing under an infinite light": {
        "camera": {"position": [0, 1e6, 0], "look_at": [0, 0, 0], "up": [1, 0, 0]},
        "image": {"width": 2, "height": 1, "max_depth": 4},
        "materials": {"a": {}, "b": {"diffuse": 1e300, "reflectance": 1e-280}},
        "objects": [
            {"type": "sphere", "material": "a", "center": [0, 0, 0], "radius": 1},
            {"type": "plane", "material": "b", "point": [0, 0, 0], "normal": [0, 0, 1]},
            {"type": "plane", "material": "b", "point": [0, 0, 1], "normal": [1, 0, 2]},
        ],
        "lights": [{"type": "directional", "color": 1e300, "direction": [1, 0, 0]}],
    },
    "huge coordinates": hard_scene(  # (the largest phongray renders: schemas.checks.MOST)
        [{**FLOOR, "point": [0, -1e60, 0]}, {**BALL, "radius": 5e59, "center": [0, 0, -1e60]}],
        [{**LAMP, "position": [1e60, 1e60, 1e60]}],
    ),
}


@pytest.mark.parametrize("name", sorted(HARD))
def test_hard_case_is_finite_and_deterministic(name):
    scene = schemas.validate_scene(HARD[name])
    image = scene.image
    first = Renderer(scene).chunk(0, image.width * image.height)
    assert not np.any(np.isnan(first))
    if "infinite light" not in name:  # 1e300 × 1e300 is rightly +inf there (and clamps to white)
        assert np.all(np.isfinite(first))
    again = Renderer(scene).pixels(threads=2, chunk_rays=500)
    assert np.array_equal(again, Renderer(scene).pixels(threads=1))


def test_camera_inside_a_sphere_sees_its_lit_inside():
    img = render_dict(HARD["camera inside a sphere"])
    assert img.max() > 0


def test_light_on_a_sphere_lights_the_floor_below():
    scene = HARD["light exactly on a sphere"]
    img = render_dict({**scene, "objects": [FLOOR, {**BALL, "center": [0, 1.5, 0]}]})
    assert img[-1].max() > 50


def nested_glass_and_mirror(depth, size):
    """Four nested spheres whose materials both reflect and transmit: the ray tree doubles at every bounce."""
    mats = {"glass": {"reflectance": 0.2, "transmittance": 0.7}, "mirror": {"reflectance": 0.6, "transmittance": 0.3}}
    objs = [
        {"type": "sphere", "material": ["glass", "mirror"][k % 2], "center": [0, 0, 0], "radius": 1.0 - 0.2 * k}
        for k in range(4)
    ]
    return {
        "camera": {"position": [0, 0, 3], "look_at": [0, 0, 0]},
        "image": {"width": size, "height": size, "max_depth": depth},
        "materials": mats,
        "objects": objs,
        "lights": [{"type": "point", "color": 1, "position": [2, 2, 2]}],
    }


def test_doubling_ray_tree_gives_the_same_bytes_for_any_slice_thread_count():
    scene = schemas.validate_scene(nested_glass_and_mirror(6, 24))
    first = encode_png(Renderer(scene).pixels(threads=1))
    assert encode_png(Renderer(scene).pixels(threads=2, chunk_rays=257)) == first
    assert encode_png(Renderer(scene).pixels(threads=3, chunk_rays=4096)) == first


MEMORY_SCRIPT = """
import json, sys
import schemas, tracer
tracer.render(schemas.validate_scene(json.loads(sys.argv[1])))
print(next(int(l.split()[1]) for l in open("/proc/self/status") if l.startswith("VmHWM:")) // 1024)
"""


def test_deep_doubling_ray_tree_stays_within_bounded_memory():
    out = subprocess.run(
        [sys.executable, "-c", MEMORY_SCRIPT, json.dumps(nested_glass_and_mirror(10, 48))],
        capture_output=True,
        text=True,
        check=True,
        timeout=300,
    )
    assert int(out.stdout) < 1024  # MiB: depth-first slices, not 2^10 rays per sample at once


def test_cancel_stops_a_render_inside_a_single_long_chunk():
    objs = [{"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 1.0 + k} for k in range(10_000)]
    scene = schemas.validate_scene(
        {
            "camera": {"position": [0, 0, 0.5], "look_at": [0, 0, 0]},
            "image": {"width": 48, "height": 48},
            "materials": {"m": {}},
            "objects": objs,
            "lights": [{"type": "point", "color": 1, "position": [0.2, 0.2, 0.2]}],
        }
    )
    renderer = Renderer(scene)
    asked: list[float] = []  # when cancel() first said yes

    def cancel() -> bool:
        if not asked and time.perf_counter() - started > 0.3:
            asked.append(time.perf_counter())
        return bool(asked)

    started = time.perf_counter()
    with pytest.raises(RenderCancelled):
        renderer.pixels(threads=1, cancel=cancel)
    stopped = time.perf_counter() - asked[0]
    measured("a render cancelled inside one long chunk: stopped after (s)", stopped)
    assert stopped < 3.0  # the whole chunk takes 8 s quiet (20 s and more on a busy machine); its budget is 0.2 s


@pytest.mark.parametrize("name", ["02_all_lights", "05_mesh"])
def test_a_dropped_renderer_is_freed_at_once(name):
    """No reference cycle keeps a finished render's arrays and BVH alive until the garbage collector runs: a
    long-running service or a benchmark would otherwise hold several renders' memory at a time."""
    scene = schemas.validate_scene(scene_dict(name))
    enabled = gc.isenabled()
    gc.disable()
    try:
        renderer = Renderer(scene)
        renderer.pixels(threads=2, chunk_rays=4096, cancel=lambda: False)
        alive = weakref.ref(renderer), weakref.ref(renderer.intersector), weakref.ref(renderer.intersector.bvh)
        del renderer
        assert [ref() is None for ref in alive] == [True, True, True]
    finally:
        if enabled:
            gc.enable()


def test_rows_rendered_alone_are_those_rows_of_the_image():
    from tracer.scene.variants import VARIANTS

    for name, options in (("04_whitted", None), ("08_antialiased", None), ("04_whitted", "image-flipped")):
        data = scene_dict(name)
        data["image"].update(width=40, height=30)
        scene = schemas.validate_scene(data)
        opts = () if options is None else (VARIANTS[options][0],)
        whole = Renderer(scene, *opts).pixels()
        rows = np.array([0, 1, 2, 17, 29, 5])
        assert np.array_equal(Renderer(scene, *opts).pixels_of_rows(rows, chunk_rays=64), whole[rows])


def test_the_diagnosis_passes_hold_the_images_own_colour():
    from tracer.image import quantize

    data = scene_dict("02_all_lights")
    data["image"].update(width=40, height=30)
    scene = schemas.validate_scene(data)
    got = Renderer(scene).diagnosis_passes(chunk_rays=256)
    assert np.array_equal(quantize(got["colour"]), Renderer(scene).pixels(chunk_rays=256))
    lights = [k for k, light in enumerate(scene.lights) if light.type != "ambient"]
    assert sum(got[f"diffuse:{k}"] for k in lights) == pytest.approx(got["diffuse"], abs=1e-12)


def _image_peak(side: int) -> int:
    """The peak of memory (traced) rendering a ``side``² image on one thread."""
    import tracemalloc

    data = scene_dict("01_three_spheres")
    data["image"].update(width=side, height=side)
    renderer = Renderer(schemas.validate_scene(data))
    tracemalloc.start()
    try:
        renderer.pixels(threads=1)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_an_image_holds_its_own_bytes_not_every_pixels_number():
    # the image is 3 bytes a pixel; its pixel numbers as int64 would be 8 more a pixel if held whole (they were,
    # for a while): what grows with the image must be the image, the chunks' work does not grow
    grown = (1024 * 1024 - 512 * 512) * 3
    assert _image_peak(1024) - _image_peak(512) < 1.5 * grown


def test_one_renderer_on_two_threads_at_once_gives_each_render_its_own_bytes_and_stop():
    # two calls at once on one renderer, each on its own thread with its own chunk size and cancel: each gives the
    # bytes of a render alone, and only the call whose cancel asks for it stops.  Each cancel waits at its first
    # poll for the other call to reach its own, so the two are surely under way together
    import threading

    data = scene_dict("04_whitted")
    data["image"].update(width=64, height=48)
    scene = schemas.validate_scene(data)
    alone = Renderer(scene).pixels(threads=1)
    shared = Renderer(scene)
    together = threading.Barrier(2, timeout=120)

    def cancel_once(answer):
        polls = []

        def cancel():
            if not polls:
                polls.append(1)
                together.wait()
            return answer

        return cancel

    results: dict[str, object] = {}

    def run(name, answer, **kwargs):
        try:
            results[name] = shared.pixels(cancel=cancel_once(answer), **kwargs)
        except RenderCancelled as exc:
            results[name] = exc

    threads = [
        threading.Thread(target=run, args=("kept", False), kwargs={"threads": 1, "chunk_rays": 64}),
        threading.Thread(target=run, args=("stopped", True), kwargs={"threads": 2, "chunk_rays": 1 << 22}),
    ]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert isinstance(results["stopped"], RenderCancelled)
    assert isinstance(results["kept"], np.ndarray) and np.array_equal(results["kept"], alone)
    # and two calls that both finish, of different chunk and slice sizes, give the same bytes as sequential renders
    both: dict[str, np.ndarray] = {}
    pair = [
        threading.Thread(target=lambda: both.update(a=shared.pixels(threads=1, chunk_rays=64))),
        threading.Thread(target=lambda: both.update(b=shared.pixels(threads=2, chunk_rays=1 << 22))),
    ]
    for t in pair:
        t.start()
    for t in pair:
        t.join()
    assert np.array_equal(both["a"], alone) and np.array_equal(both["b"], alone)
