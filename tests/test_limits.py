"""A render is priced by the work it does: refused up front only for what is certain, estimated from what the
scene can really spawn, and held to a budget counted while it runs (service/admission/limits.py,
service/admission/estimate.py)."""

import json
import subprocess
import sys
import time

import pytest
from fastapi.testclient import TestClient
from test_render import nested_glass_and_mirror

import schemas
from service.admission.limits import LimitError, beyond_limits, check_scene, estimated_cost, per_ray_factor
from service.cli import main
from service.http.app import create_app
from service.settings import Settings
from tracer import Renderer

from helpers import SCENES, scene_dict

JSON = {"content-type": "application/json"}
ROOT = SCENES.parent.parent
HOMEWORK = ROOT / "examples" / "09_cornell_homework.json"


@pytest.fixture(scope="module")
def api():
    return TestClient(create_app(Settings()))


def whitted(width=640, height=480, samples=2):
    data = scene_dict("04_whitted")
    data["image"].update(width=width, height=height, samples=samples)
    return data


def homework(width=320, height=240):
    data = json.loads(HOMEWORK.read_text())
    data["image"].update(width=width, height=height)
    return data


@pytest.mark.parametrize(
    "data",
    [homework(), homework(640, 480), whitted()],
    ids=["homework 320×240", "homework 640×480", "whitted 640×480 2×2"],
)
def test_a_course_homework_renders_and_grades_with_the_default_limits(api, data):
    """A Cornell box with a mirror ball, a glass ball, an area light and a spot, depth 5 and 2×2 samples, and the
    Whitted example at 640×480 with 2×2 samples: the worst-case tree refused them (4.4e8, 8.5e8 > 1e8)."""
    body = json.dumps(data)
    res = api.post("/render", content=body, headers=JSON)
    assert res.status_code == 200, res.text
    graded = api.post("/grade", data={"scene": body}, files={"image": ("mine.png", res.content, "image/png")})
    assert graded.status_code == 200 and graded.json()["passed"], graded.text


def test_the_ray_tree_bomb_is_stopped_fast_naming_the_setting(api):
    """Nested glass and mirror spheres at depth 16: 2^17 rays per camera ray.  It passes every check made up
    front; the budget counted as it runs stops it with a 422 that names the setting and says what to do."""
    started = time.monotonic()
    res = api.post("/render", content=json.dumps(nested_glass_and_mirror(16, 128)), headers=JSON)
    assert res.status_code == 422
    assert time.monotonic() - started < 60  # stopped after seconds (2.7 s on 2 cores), far within render_timeout
    detail = res.json()["detail"]
    assert "max_cost" in detail and "PHONGRAY_MAX_COST" in detail and "image.max_depth" in detail, detail


def test_a_pass_of_the_bomb_is_held_to_the_same_budget(api):
    res = api.post("/render?pass=reflection", content=json.dumps(nested_glass_and_mirror(16, 128)), headers=JSON)
    assert res.status_code == 422 and "PHONGRAY_MAX_COST" in res.json()["detail"]


BOMB_SCRIPT = """
import json, sys
from fastapi.testclient import TestClient
from service.http.app import create_app
from service.cli import main
from service.settings import Settings
res = TestClient(create_app(Settings())).post("/render", content=sys.stdin.read(),
                                              headers={"content-type": "application/json"})
print(res.status_code, next(int(l.split()[1]) for l in open("/proc/self/status") if l.startswith("VmHWM:")) // 1024)
"""


def test_the_ray_tree_bomb_is_stopped_in_bounded_memory():
    out = subprocess.run(
        [sys.executable, "-c", BOMB_SCRIPT],
        input=json.dumps(nested_glass_and_mirror(16, 256)),
        capture_output=True,
        text=True,
        check=True,
        timeout=600,
    )
    status, peak = map(int, out.stdout.split())
    assert status == 422 and peak < 1024  # MiB, the whole process


def test_a_render_stopped_by_the_memory_budget_names_its_setting():
    api = TestClient(create_app(Settings(max_ray_bytes=1000)))
    res = api.post("/render", content=json.dumps(nested_glass_and_mirror(4, 32)), headers=JSON)
    assert res.status_code == 422 and "PHONGRAY_MAX_RAY_BYTES" in res.json()["detail"]


def test_only_what_is_certain_is_refused_up_front():
    """The camera rays are certain; the tree they spawn is not: the depth-16 bomb passes the checks made up front
    (the budget stops it), a scene whose camera rays alone are over max_cost does not."""
    check_scene(schemas.validate_scene(nested_glass_and_mirror(16, 128)), Settings())
    with pytest.raises(LimitError, match="PHONGRAY_MAX_COST"):
        check_scene(schemas.validate_scene(nested_glass_and_mirror(0, 4096)), Settings(max_cost=1e7))


@pytest.mark.parametrize("name", [p.stem for p in sorted((ROOT / "examples").glob("*.json"))])
def test_the_estimate_is_within_ten_times_of_the_work_counted(name):
    data = json.loads((ROOT / "examples" / f"{name}.json").read_text())
    data["image"].update(width=64, height=48)
    scene = schemas.validate_scene(data)
    renderer = Renderer(scene)
    renderer.pixels(threads=1)
    counted = renderer.spent * per_ray_factor(scene)
    assert counted / 10 < estimated_cost(scene) < counted * 10


def test_the_estimate_grows_with_the_tree_only_where_mirrors_and_glass_see_each_other():
    bomb = schemas.validate_scene(nested_glass_and_mirror(16, 128))
    assert estimated_cost(bomb) > 10 * Settings().max_cost
    apart = nested_glass_and_mirror(16, 128)  # the same spheres side by side, far apart: few rays go between
    for k, obj in enumerate(apart["objects"]):
        obj.update(center=[4.0 * k - 6, 0, -20], radius=0.5)
    assert estimated_cost(schemas.validate_scene(apart)) < Settings().max_cost / 10


def test_thousands_of_spheres_around_the_eye_are_priced_as_such():
    objs = [{"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 1.0 + k} for k in range(10_000)]
    data = {
        "camera": {"position": [0, 0, 0.5], "look_at": [0, 0, 0]},
        "image": {"width": 128, "height": 128},
        "materials": {"m": {}},
        "objects": objs,
        "lights": [{"type": "point", "color": 1, "position": [0, 0, 0]}],
    }
    inside = schemas.validate_scene(data)
    assert estimated_cost(inside) > Settings().max_cost and beyond_limits(inside, Settings())
    data["camera"]["position"] = [0, 0, 2e4]
    assert estimated_cost(schemas.validate_scene(data)) < estimated_cost(inside) / 100


def test_validate_warns_of_the_limits_a_service_would_hold_the_scene_to():
    assert beyond_limits(schemas.validate_scene(homework(640, 480)), Settings()) == []
    said = beyond_limits(schemas.validate_scene(nested_glass_and_mirror(16, 128)), Settings())
    assert len(said) == 1 and "PHONGRAY_MAX_COST" in said[0]


def test_phongray_validate_warns_but_calls_the_scene_valid(tmp_path, capsys):
    path = tmp_path / "bomb.json"
    path.write_text(json.dumps(nested_glass_and_mirror(16, 128)))
    assert main(["validate", str(path)]) == 0
    out, err = capsys.readouterr()
    assert out == f"{path}: valid\n"
    assert err.startswith(f"{path}: warning: ") and "PHONGRAY_MAX_COST" in err and err.count("\n") == 1


def test_phongray_grade_holds_the_scene_to_the_limits_only_when_asked(tmp_path, capsys):
    path, image = tmp_path / "bomb.json", tmp_path / "mine.png"
    path.write_text(json.dumps(nested_glass_and_mirror(16, 128)))
    image.write_bytes(b"not looked at: the reference is refused first")
    assert main(["grade", str(path), str(image), "--limits"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"phongray: {path}: scene: the render was stopped") and err.count("\n") == 1
    assert "max_cost = 1e+08, set by PHONGRAY_MAX_COST" in err


def test_the_estimate_of_a_huge_depth_is_made_at_once():
    """Depths past 64 grow as the last one did: nested glass at depth 10^9 is infinite, a hall of mirrors
    linear in the depth, and neither walks 10^9 depths."""
    started = time.monotonic()
    assert estimated_cost(schemas.validate_scene(nested_glass_and_mirror(10**9, 64))) == float("inf")
    mirrors = nested_glass_and_mirror(10**9, 64)
    mirrors["materials"] = {"glass": {"reflectance": 0.9}, "mirror": {"reflectance": 0.9}}
    assert 1e11 < estimated_cost(schemas.validate_scene(mirrors)) < float("inf")
    assert time.monotonic() - started < 10  # (about 2 ms)


def test_the_estimate_is_within_ten_times_of_the_work_on_generated_scenes():
    """The differential fuzz test's scenes (rooms, nested glass, meshes, cameras anywhere): 150 of them were
    within 0.88–2.2×."""
    from generator import scene

    for seed in range(60):
        family, data = scene(seed)
        generated = schemas.validate_scene(data)
        renderer = Renderer(generated)
        renderer.pixels(threads=1)
        counted = renderer.spent * per_ray_factor(generated)
        assert counted / 10 < estimated_cost(generated) < counted * 10, (family, seed)


def huge_beside_tiny(width=64, height=48):
    """5,001 tiny spheres and 4,999 spheres far larger than the median: those are tested against every ray, so
    each ray makes 5,000 exact tests while the per-ray factor (log2 of 10,000 spheres) prices it at 2.7."""
    objs = [
        {
            "type": "sphere",
            "material": "m",
            "center": [(k % 70) * 0.01 - 0.35, (k // 70) * 0.01 - 0.35, 0],
            "radius": 0.001,
        }
        for k in range(5001)
    ]
    objs += [
        {"type": "sphere", "material": "m", "center": [0, 0, -1000 - k], "radius": 500.0 + k * 0.01}
        for k in range(4999)
    ]
    return {
        "camera": {"position": [0, 0, 30], "look_at": [0, 0, 0]},
        "image": {"width": width, "height": height},
        "materials": {"m": {}},
        "objects": objs,
        "lights": [{"type": "point", "color": 1, "position": [0, 50, 0]}],
    }


def test_rays_that_each_meet_thousands_of_surfaces_are_stopped_naming_the_setting():
    """Its rays are few (1.3·10⁴ of cost) but their exact tests are 2.4·10⁷: at 640×480 the render took 64 s for
    a cost of 1.6·10⁶, and twice that size ran into render_timeout (503) instead of the budget (422).  The exact
    tests are counted as well, 4 per unit of max_cost."""
    api = TestClient(create_app(Settings(max_cost=1e6)))
    res = api.post("/render", content=json.dumps(huge_beside_tiny()), headers=JSON)
    assert res.status_code == 422, res.text[:300]
    assert "PHONGRAY_MAX_COST" in res.json()["detail"] and "surfaces" in res.json()["detail"]


@pytest.mark.parametrize("name", ["04_whitted", "01_three_spheres", "05_mesh", "08_antialiased"])
def test_honest_scenes_make_few_exact_tests_per_unit_of_cost(name):
    from service.admission.limits import TESTS_PER_COST

    scene = schemas.validate_scene(scene_dict(name))
    renderer = Renderer(scene)
    renderer.pixels(threads=2)
    assert renderer.tests <= TESTS_PER_COST / 4 * renderer.spent * per_ray_factor(scene)


def test_the_homework_and_nested_glass_make_few_exact_tests_per_unit_of_cost():
    from service.admission.limits import TESTS_PER_COST

    for data in (homework(160, 120), nested_glass_and_mirror(7, 64)):
        scene = schemas.validate_scene(data)
        renderer = Renderer(scene)
        renderer.pixels(threads=2)
        assert renderer.tests <= TESTS_PER_COST * 0.75 * renderer.spent * per_ray_factor(scene)
