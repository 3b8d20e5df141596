"""End to end against a real ``phongray serve`` on 127.0.0.1, and the playground in headless Chromium."""

import json
import os
import shutil
import subprocess
import sys
import urllib.error
import urllib.request
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from service.client import ServerError, post_form, post_json

from helpers import SCENES, scene_dict
from server import running_server

SCENE = (SCENES / "01_three_spheres.json").read_bytes()
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    with running_server(  # (queue_wait 0: a render finding the one slot taken is refused at once)
        tmp_path_factory.mktemp("server"),
        max_concurrent_renders="1",
        max_body_bytes="200000",
        render_threads="1",
        queue_wait="0",
    ) as (url, _):
        yield url


def status_of(func, *args, **kwargs):
    try:
        func(*args, **kwargs)
        return 200
    except ServerError as exc:
        return exc.status


def test_render_matches_the_cli_bytes(server, tmp_path):
    out = tmp_path / "cli.png"
    subprocess.run(
        [sys.executable, "-m", "service.cli", "render", str(SCENES / "01_three_spheres.json"), "-o", str(out), "-q"],
        check=True,
    )
    assert post_json(server, "/render", SCENE) == out.read_bytes()


def test_304_on_matching_etag(server):
    req = urllib.request.Request(server + "/render", data=SCENE, headers={"content-type": "application/json"})
    with urllib.request.urlopen(req) as res:
        etag = res.headers["etag"]
    req = urllib.request.Request(
        server + "/render", data=SCENE, headers={"content-type": "application/json", "if-none-match": etag}
    )
    with pytest.raises(urllib.error.HTTPError) as info:
        urllib.request.urlopen(req)
    info.value.close()
    assert info.value.code == 304


def test_grade_pass_and_fail(server):
    png = post_json(server, "/render", SCENE)
    passed = json.loads(post_form(server, "/grade", {"scene": SCENE}, {"image": ("a.png", png, "image/png")}))
    assert passed["passed"] is True and passed["mean_abs_error"] == 0
    other = post_json(server, "/render", (SCENES / "07_spotlights.json").read_bytes())
    failed = json.loads(post_form(server, "/grade", {"scene": SCENE}, {"image": ("b.png", other, "image/png")}))
    assert failed["passed"] is False


def test_413_and_422(server):
    assert status_of(post_json, server, "/render", b" " * 300_000) == 413
    assert status_of(post_json, server, "/render", b'{"camera": 1}') == 422


def test_burst_beyond_the_slot_count_gets_200_or_503_and_the_service_stays_healthy(server):
    data = scene_dict("03_soft_shadows")
    bodies = []
    for k in range(50):  # 50 concurrent, distinct scenes, so the cache cannot answer for the renderer
        data["image"]["background"] = [0.01 * k, 0, 0]
        bodies.append(json.dumps(data).encode())
    with ThreadPoolExecutor(max_workers=50) as pool:
        codes = list(pool.map(lambda b: status_of(post_json, server, "/render", b), bodies))
    assert set(codes) <= {200, 503}
    assert 503 in codes and 200 in codes
    with urllib.request.urlopen(server + "/healthz") as res:
        health = json.loads(res.read())
    assert health["status"] == "ok"
    assert status_of(post_json, server, "/render", SCENE) == 200


def test_cli_talks_to_the_server(server, tmp_path):
    out = tmp_path / "s.png"
    run = [sys.executable, "-m", "service.cli"]
    spots = str(SCENES / "07_spotlights.json")
    assert subprocess.run([*run, "render", spots, "-o", str(out), "--server", server]).returncode == 0
    assert (
        subprocess.run(
            [*run, "grade", str(SCENES / "07_spotlights.json"), str(out), "--server", server], capture_output=True
        ).returncode
        == 0
    )
    assert (
        subprocess.run(
            [*run, "grade", str(SCENES / "01_three_spheres.json"), str(out), "--server", server], capture_output=True
        ).returncode
        == 1
    )  # another scene's image: fails
    small = tmp_path / "small.png"
    assert (
        subprocess.run(
            [*run, "render", str(SCENES / "07_spotlights.json"), "-o", str(small), "--width", "20", "--server", server]
        ).returncode
        == 0
    )
    wrong = subprocess.run(
        [*run, "grade", str(SCENES / "07_spotlights.json"), str(small), "--server", server], capture_output=True
    )
    assert wrong.returncode == 2 and b"20" in wrong.stderr  # wrong size: bad input
    assert subprocess.run([*run, "validate", str(SCENES / "05_mesh.json"), "--server", server]).returncode == 0


@pytest.fixture(scope="module")
def browser():
    if CHROMIUM is None:
        if os.environ.get("PHONGRAY_REQUIRE_BROWSER"):
            pytest.fail("Chromium is required (PHONGRAY_REQUIRE_BROWSER is set) but not installed")
        pytest.skip("Chromium is not installed (CI installs it and sets PHONGRAY_REQUIRE_BROWSER)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(
            executable_path=CHROMIUM, args=["--no-sandbox", "--disable-gpu", "--disable-background-networking"]
        )
        yield b
        b.close()


SHOTS = os.environ.get("PHONGRAY_SCREENSHOTS")  # a folder: the playground tests leave their screenshots there


def shot(page, name: str, tmp_path) -> None:
    page.screenshot(path=str(Path(SHOTS) / name if SHOTS else tmp_path / name))


def test_playground_picks_an_example_renders_it_and_offers_the_png(server, browser, tmp_path):
    page = offline_page(browser, server)
    page.goto(server + "/")
    assert page.locator("h1").inner_text() == "phongray playground"
    names = page.locator("#examples option").all_inner_texts()
    assert names == sorted(p.stem for p in (SCENES.parent.parent / "examples").glob("*.json"))
    page.select_option("#examples", "04_whitted")
    assert '"reflectance"' in page.input_value("#scene")
    page.keyboard.press("Control+Enter")
    page.wait_for_function("() => document.getElementById('image').naturalWidth > 0", timeout=20_000)
    assert page.evaluate("document.getElementById('image').naturalWidth") == 160
    assert page.evaluate("document.getElementById('image').getBoundingClientRect().width") == 480  # 3× crisp
    assert "160×120 px" in page.inner_text("#info") and page.locator("#download").count() == 1
    shot(page, "playground.png", tmp_path)
    assert page.outside == []
    page.close()


def test_playground_shows_a_limit_as_a_refusal_naming_its_setting(server, browser):
    """A valid scene the service stops (nested glass and mirrors at depth 16: its budget) is a refusal over the
    image that names the setting, not a list of the scene's errors."""
    from test_render import nested_glass_and_mirror

    page = offline_page(browser, server)
    page.goto(server + "/")
    page.fill("#scene", json.dumps(nested_glass_and_mirror(16, 128), indent=2))
    page.click("#render")
    page.wait_for_selector("#refusal:not([hidden])", timeout=60_000)
    said = page.inner_text("#refusal")
    assert said.startswith("Not rendered: scene: the render was stopped") and "PHONGRAY_MAX_COST" in said
    assert page.locator("#errors li").count() == 0 and "stale" not in page.get_attribute("#view", "class")
    page.close()


def test_playground_marks_an_error_beside_its_line_after_scrolling(server, browser):
    page = offline_page(browser, server)
    page.set_viewport_size({"width": 1400, "height": 700})
    page.goto(server + "/")
    page.select_option("#examples", "05_mesh")
    lines = page.input_value("#scene").split("\n")
    assert len(lines) > 130
    target = max(i for i, l in enumerate(lines) if '"material"' in l)  # near the end
    lines[target] = lines[target].replace('"material": "', '"material": "zz', 1)
    page.fill("#scene", "\n".join(lines))
    page.click("#render")
    page.wait_for_selector("#errors li", timeout=20_000)
    item = page.locator("#errors li").filter(has_text="unknown material")
    assert item.inner_text().startswith(f"line {target + 1}: ")
    item.click()
    marker = page.locator(f"#gutter .bad[data-line='{target + 1}']")
    box = marker.bounding_box()
    editor = page.locator("#editor").bounding_box()
    assert editor["y"] <= box["y"] and box["y"] + box["height"] <= editor["y"] + editor["height"]  # in view
    area = page.locator("#scene").bounding_box()
    line_height = 18
    line_top = area["y"] + 6 + target * line_height  # the text's own line, where the scroll put it
    assert abs(box["y"] - line_top) <= 2, (box, line_top)
    page.close()


def test_playground_marks_a_syntax_error(server, browser):
    page = offline_page(browser, server)
    page.goto(server + "/")
    text = page.input_value("#scene").replace('"width": 160,', '"width": 160,,', 1)
    page.fill("#scene", text)
    page.click("#render")
    page.wait_for_selector("#gutter .bad", timeout=20_000)
    line = next(i for i, l in enumerate(text.splitlines(), 1) if ",," in l)
    assert page.locator("#gutter .bad").get_attribute("data-line") == str(line)
    assert "stale" not in (page.get_attribute("#view", "class") or "")  # no image yet: nothing to mark stale
    page.close()


def test_playground_asks_before_replacing_an_edited_scene_and_keeps_it_over_a_reload(server, browser):
    page = offline_page(browser, server)
    page.goto(server + "/")
    asked: list[str] = []
    answer = {"accept": False}

    def on_dialog(dialog):
        asked.append(dialog.message)
        dialog.accept() if answer["accept"] else dialog.dismiss()

    page.on("dialog", on_dialog)
    page.select_option("#examples", "02_all_lights")  # not edited: replaced without a question
    assert asked == [] and '"spot"' in page.input_value("#scene")
    edited = page.input_value("#scene").replace('"width": 160', '"width": 161', 1)
    page.fill("#scene", edited)
    page.select_option("#examples", "04_whitted")  # edited: asked, and "no" keeps the edits
    assert len(asked) == 1 and "04_whitted" in asked[0]
    assert page.input_value("#scene") == edited and page.input_value("#examples") == "02_all_lights"
    page.reload()
    assert page.input_value("#scene") == edited  # the edits survive a reload
    answer["accept"] = True
    page.select_option("#examples", "04_whitted")
    assert len(asked) == 2 and '"reflectance"' in page.input_value("#scene")
    page.reload()
    assert '"reflectance"' in page.input_value("#scene") and page.input_value("#examples") == "04_whitted"
    assert page.outside == []
    page.close()


def test_playground_opens_a_scene_file(server, browser, tmp_path):
    page = offline_page(browser, server)
    page.goto(server + "/")
    scene = tmp_path / "mine.json"
    scene.write_text((SCENES / "07_spotlights.json").read_text())
    assert page.locator("#open").is_visible()
    page.set_input_files("#file", str(scene))
    page.wait_for_function("() => document.getElementById('scene').value.includes('spot')", timeout=10_000)
    assert page.input_value("#scene") == scene.read_text()
    page.close()


def test_playground_says_from_cache_for_a_cached_image(server, browser):
    page = offline_page(browser, server)
    page.goto(server + "/")
    data = json.loads(page.input_value("#scene"))
    data["image"]["background"] = [0.013, 0.021, 0.034]  # a scene no other test rendered
    page.fill("#scene", json.dumps(data, indent=2))
    for says in ("rendered in ", "from cache"):
        page.evaluate("document.getElementById('info').textContent = ''")
        page.click("#render")
        page.wait_for_function("() => document.getElementById('info').textContent.includes('px')", timeout=20_000)
        assert says in page.inner_text("#info")
    assert "0.000 s" not in page.inner_text("#info")
    page.close()


def test_playground_lists_errors_in_line_order_and_clears_them_as_the_scene_is_edited(server, browser):
    page = offline_page(browser, server)
    page.goto(server + "/")
    data = json.loads(page.input_value("#scene"))
    data["objects"][0]["material"] = "glod"  # found after the fields' errors, but on an earlier line
    data["objects"][-1]["radius"] = -1
    page.fill("#scene", json.dumps(data, indent=2))
    page.click("#render")
    page.wait_for_selector("#errors li", timeout=20_000)
    items = page.locator("#errors li").all_inner_texts()
    lines = [int(item.split(":")[0].removeprefix("line ")) for item in items]
    assert len(items) == 2 and lines == sorted(lines) and "unknown material" in items[0], items
    assert page.locator("#gutter .bad").count() == 2
    page.focus("#scene")
    page.keyboard.press("End")
    page.keyboard.type(" ")
    assert page.locator("#errors li").count() == 0 and page.locator("#gutter .bad").count() == 0
    page.close()


def variant_png(text: bytes, name: str) -> bytes:
    import schemas
    import tracer
    from tracer.scene.variants import VARIANTS

    return tracer.encode_png(tracer.Renderer(schemas.load_scene(text), VARIANTS[name][0]).pixels())


def test_playground_grades_right_and_wrong_images(server, browser, tmp_path):
    right = tmp_path / "right.png"
    right.write_bytes(post_json(server, "/render", SCENE))
    wrong = tmp_path / "wrong.png"
    data = json.loads(SCENE)
    data["lights"] = data["lights"][:1]
    wrong.write_bytes(post_json(server, "/render", json.dumps(data).encode()))
    page = offline_page(browser, server)
    page.goto(server + "/")
    page.click("#tab-grade")
    page.set_input_files("#upload", str(right))
    page.wait_for_selector("#verdict.pass", timeout=20_000)
    page.set_input_files("#upload", str(wrong))
    page.wait_for_selector("#verdict.fail", timeout=20_000)
    page.wait_for_function(
        "() => { const i = document.getElementById('grade-heat-map'); return i && i.naturalWidth === 160; }",
        timeout=20_000,
    )
    assert "fraction_off_nearby" in page.inner_text("#numbers")
    assert page.inner_text("#verdict").startswith("FAIL: ") and "off even nearby" in page.inner_text("#verdict")
    legend = page.inner_text("#legend")
    assert "brighter than the reference" in legend and "darker than the reference" in legend
    # (a light left out: no mistake fits; most of the difference is that light's terms, in a student's words)
    assert page.is_visible("#diagnosis") and page.inner_text("#likely").startswith(
        ("Likely: the ", "No known mistake fits exactly: most of the difference is the ")
    )
    unshadowed = tmp_path / "unshadowed.png"
    unshadowed.write_bytes(variant_png(SCENE, "no-shadows"))
    page.set_input_files("#upload", str(unshadowed))
    page.wait_for_function(
        "() => document.getElementById('likely').textContent.startsWith('Likely: no shadow')", timeout=30_000
    )
    page.wait_for_function(
        "() => { const i = document.getElementById('grade-heat-map'); return i && i.naturalWidth === 160; }",
        timeout=20_000,
    )
    assert "failing pixels show: the first " in page.inner_text("#evidence")  # (objects by place and kind)
    shot(page, "playground-grade.png", tmp_path)
    assert page.outside == []
    page.close()


def test_playground_grades_a_ppm_and_shows_it(server, browser, tmp_path):
    import io

    import numpy as np
    from PIL import Image

    pixels = np.asarray(Image.open(io.BytesIO(post_json(server, "/render", SCENE))).convert("RGB"))
    h, w, _ = pixels.shape
    (tmp_path / "image.ppm").write_bytes(f"P6\n# a student's\n{w} {h}\n255\n".encode() + pixels.tobytes())
    text = "\n".join(" ".join(map(str, p)) for p in pixels.reshape(-1, 3))
    (tmp_path / "plain.ppm").write_text(f"P3\n{w} {h}\n255\n{text}\n")
    page = offline_page(browser, server)
    page.goto(server + "/")
    page.click("#tab-grade")
    for name in ("image.ppm", "plain.ppm"):
        page.set_input_files("#upload", str(tmp_path / name))
        page.wait_for_selector("#verdict.pass", timeout=20_000)
        page.wait_for_function(
            "() => { const i = document.getElementById('grade-submission'); return i && i.naturalWidth === 160; }",
            timeout=20_000,
        )
        shown = page.evaluate(
            """() => { const i = document.getElementById('grade-submission'), c = document.createElement('canvas');
                c.width = i.naturalWidth; c.height = i.naturalHeight; const x = c.getContext('2d');
                x.drawImage(i, 0, 0); return Array.from(x.getImageData(80, 60, 1, 1).data.slice(0, 3)); }"""
        )
        assert shown == pixels[60, 80].tolist(), name  # the submission shown is its very pixels
    assert page.outside == []
    page.close()


def test_playground_with_an_api_key(tmp_path, browser):
    with running_server(tmp_path, api_key="opensesame") as (url, _):
        page = browser.new_page()
        page.goto(url + "/")
        page.click("#render")
        page.wait_for_function(
            "() => document.getElementById('status').textContent.includes('API key')", timeout=20_000
        )
        page.fill("#key", "opensesame")
        page.click("#render")
        page.wait_for_function("() => document.getElementById('image').naturalWidth > 0", timeout=20_000)
        page.reload()
        assert page.input_value("#key") == "opensesame"  # kept for the session
        page.close()


def offline_page(browser, server):
    """A page that may reach the server only; any other request is stopped and remembered."""
    page = browser.new_page(viewport={"width": 1400, "height": 900})
    page.outside = []

    def route(r):
        if r.request.url.startswith(server):
            r.continue_()
        else:
            page.outside.append(r.request.url)
            r.abort()

    page.route("**/*", route)
    return page


def try_out(page, operation: str):
    """Open an operation in Swagger UI; return its locator (try-it-out is on from the start)."""
    op = page.locator(f"#operations-default-{operation}")
    op.locator(".opblock-summary").click()
    op.locator("button.execute").wait_for(timeout=10_000)
    return op


def test_swagger_ui_works_offline_and_tries_render_validate_and_grade(server, browser, tmp_path):
    page = offline_page(browser, server)
    page.goto(server + "/docs")
    page.wait_for_selector(".opblock", timeout=20_000)
    assert page.locator(".opblock-summary-path").all_inner_texts() == [
        "/render",
        "/validate",
        "/grade",
        "/schema",
        "/healthz",
    ]
    op = try_out(page, "render_scene_render_post")
    stub = op.locator("textarea.body-param__text").input_value()  # what "Try it out" sends untouched
    assert json.loads(stub) == json.loads(SCENE)
    op.locator("button.execute").click()
    image = op.locator(".live-responses-table img").first
    image.wait_for(timeout=20_000)
    assert image.evaluate("i => i.naturalWidth") == 160

    op = try_out(page, "validate_validate_post")
    op.locator("textarea.body-param__text").fill(SCENE.decode().replace('"radius": 0.9', '"radius": -0.9'))
    op.locator("button.execute").click()
    op.locator(".live-responses-table .response-col_status").first.wait_for(timeout=20_000)
    assert "objects[2].radius" in op.locator(".live-responses-table").inner_text()

    png = tmp_path / "reference.png"
    png.write_bytes(post_json(server, "/render", SCENE))
    op = try_out(page, "grade_grade_post")
    op.locator("tr[data-property-name=scene] input").fill(SCENE.decode())  # the form's scene field, as text
    op.locator("tr[data-property-name=image] input[type=file]").set_input_files(str(png))
    op.locator("button.execute").click()
    op.locator(".live-responses-table .response-col_status").first.wait_for(timeout=20_000)
    assert '"passed": true' in op.locator(".live-responses-table").inner_text()
    page.screenshot(path=str(tmp_path / "swagger.png"))
    assert page.outside == []
    page.close()


def test_redoc_works_offline(server, browser):
    page = offline_page(browser, server)
    page.goto(server + "/redoc")
    page.wait_for_selector("text=Render a scene to a PNG", timeout=20_000)
    page.wait_for_timeout(500)
    assert page.outside == []  # (its sidebar's logo from a CDN is stopped by the page's own policy, unasked)
    page.close()
