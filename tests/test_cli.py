"""The phongray command: renders, validates, and never prints a traceback."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from service.cli import main
from tracer import decode_png

from helpers import SCENES, reference


def run(*args, stdin=None):
    return subprocess.run([sys.executable, "-m", "service.cli", *args], capture_output=True, input=stdin, timeout=120)


def test_render_writes_the_reference_image(tmp_path):
    out = tmp_path / "out.png"
    assert main(["render", str(SCENES / "01_three_spheres.json"), "-o", str(out), "-q"]) == 0
    assert (decode_png(out.read_bytes()) == reference("01_three_spheres")).mean() > 0.999


def test_a_render_starts_without_the_settings_or_pillow(tmp_path):
    """A render's start-up is its users' wait: with no PHONGRAY_* variable set, it imports neither
    pydantic-settings (about 0.1 s) nor Pillow, which only grading needs."""
    out = tmp_path / "out.png"
    code = (
        "import sys; from service.cli import main; "
        f"code = main(['render', {str(SCENES / '07_spotlights.json')!r}, '-o', {str(out)!r}, '-q']); "
        "print(code, sorted(m for m in ('pydantic_settings', 'PIL') if m in sys.modules))"
    )
    env = {k: v for k, v in os.environ.items() if not k.upper().startswith("PHONGRAY_")}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert done.stdout.split() == ["0", "[]"], done.stderr
    assert out.stat().st_size > 0


def test_a_large_render_on_forked_processes_is_the_same_bytes(tmp_path):
    """`phongray render` spreads a large render over forked processes (service.render.rendering.render_forked): the
    PNG is the same bytes as a render on threads."""
    import schemas
    import tracer
    from service.render.rendering import FORKED_RAYS

    data = json.loads((SCENES / "02_all_lights.json").read_text())
    data["image"].update(width=640, height=480)
    assert 640 * 480 >= FORKED_RAYS
    scene, out = tmp_path / "scene.json", tmp_path / "out.png"
    scene.write_text(json.dumps(data))
    done = run("render", str(scene), "-o", str(out), "--threads", "2", "-q")
    assert done.returncode == 0, done.stderr
    assert out.read_bytes() == tracer.encode_png(tracer.render(schemas.validate_scene(data), threads=2))


def test_bands_on_forked_processes_are_the_rows_of_the_render():
    import schemas
    import tracer
    from service.render.rendering import render_forked

    data = json.loads((SCENES / "08_antialiased.json").read_text())
    data["image"].update(width=48, height=37)
    scene = schemas.validate_scene(data)
    done = []
    assert np.array_equal(render_forked(scene, 2, lambda a, b: done.append((a, b))), tracer.render(scene, threads=1))
    assert done[-1] == (48 * 37, 48 * 37) and len(done) == 16  # every band, its progress told


def test_render_overrides_size_and_samples(tmp_path):
    out = tmp_path / "out.png"
    assert (
        main(
            [
                "render",
                str(SCENES / "01_three_spheres.json"),
                "-o",
                str(out),
                "--width",
                "20",
                "--height",
                "10",
                "--samples",
                "2",
                "-q",
            ]
        )
        == 0
    )
    assert decode_png(out.read_bytes()).shape == (10, 20, 3)


def test_validate_ok_and_errors(tmp_path, capsys):
    assert main(["validate", str(SCENES / "05_mesh.json")]) == 0
    bad = tmp_path / "bad.json"
    bad.write_text(
        json.dumps(
            {
                "camera": {"position": [0, 0, 1], "look_at": [0, 0, 0]},
                "image": {"width": 1, "height": 1},
                "objects": [{"type": "sphere", "material": "x", "center": [0, 0, 0], "radius": -1}],
            }
        )
    )
    assert main(["validate", str(bad)]) == 1
    assert "objects[0].radius: must be > 0" in capsys.readouterr().out


def test_validate_prints_names_that_are_not_valid_unicode(tmp_path):
    data = json.loads((SCENES / "01_three_spheres.json").read_text())
    data["objects"][0]["material"] = "\ud800"
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(data))  # ASCII: the lone surrogate as the escape \ud800
    result = run("validate", str(bad))
    assert result.returncode == 1 and b"Traceback" not in result.stderr
    assert b"unknown material '\\ud800'" in result.stdout


def test_validate_prints_its_errors_in_the_order_of_their_lines(tmp_path, capsys):
    """The unknown material (found after the fields' errors) comes first, on its line."""
    data = json.loads((SCENES / "01_three_spheres.json").read_text())
    data["objects"][0]["material"] = "glod"
    data["objects"][2]["radius"] = -1
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(data, indent=2))
    assert main(["validate", str(bad)]) == 1
    printed = capsys.readouterr().out.splitlines()
    numbers = [int(line.split(":")[1]) for line in printed]
    assert len(printed) == 2 and numbers == sorted(numbers) and numbers[0] < numbers[1]
    assert "objects[0].material: unknown material 'glod'" in printed[0] and "radius: must be > 0" in printed[1]


def test_schema_prints_json(capsys):
    assert main(["schema"]) == 0
    assert json.loads(capsys.readouterr().out)["type"] == "object"


@pytest.mark.parametrize("content", [b"", b"{", b"\x89PNG\r\n", b"[]", b'{"camera": 1}', b"[" * 50000])
def test_bad_input_gives_one_line_and_no_traceback(tmp_path, content):
    path = tmp_path / "scene.json"
    path.write_bytes(content)
    for command in (["validate", str(path)], ["render", str(path), "-o", str(tmp_path / "x.png")]):
        result = run(*command)
        assert result.returncode != 0
        assert b"Traceback" not in result.stderr + result.stdout


def test_missing_file_and_unwritable_output(tmp_path):
    result = run("render", str(tmp_path / "missing.json"), "-o", str(tmp_path / "x.png"))
    assert result.returncode == 2 and b"cannot read" in result.stderr and b"Traceback" not in result.stderr
    result = run("render", str(SCENES / "07_spotlights.json"), "-o", str(tmp_path / "no" / "dir" / "x.png"))
    assert result.returncode == 2 and b"cannot write" in result.stderr


def test_render_from_stdin_to_stdout():
    result = run("render", "-", "-o", "-", "-q", stdin=(SCENES / "07_spotlights.json").read_bytes())
    assert result.returncode == 0 and result.stdout.startswith(b"\x89PNG")


def test_progress_bar_draws_only_when_enabled_and_late(capsys):
    from service.cli import ProgressBar

    quiet = ProgressBar(delay=0.0)
    quiet.enabled = False
    quiet(5, 10)
    bar = ProgressBar(delay=0.0)
    bar.enabled = True  # as on a terminal
    bar(5, 10)
    bar.close()
    late = ProgressBar(delay=3600.0)
    late.enabled = True
    late(5, 10)
    err = capsys.readouterr().err
    assert err.count("50.0%") == 1 and err.endswith("\n")


def test_absurd_image_size_is_refused_not_attempted(tmp_path):
    data = json.loads((SCENES / "01_three_spheres.json").read_text())
    data["image"]["width"] = 10**12
    path = tmp_path / "huge.json"
    path.write_text(json.dumps(data))
    result = run("render", str(path), "-o", str(tmp_path / "x.png"))
    assert result.returncode == 2 and b"more than phongray renders" in result.stderr


def test_absurd_area_light_grid_is_refused_not_attempted(tmp_path):
    data = json.loads((SCENES / "03_soft_shadows.json").read_text())
    data["lights"][1]["samples"] = [10**9, 10**9]
    path = tmp_path / "huge.json"
    path.write_text(json.dumps(data))
    result = run("render", str(path), "-o", str(tmp_path / "x.png"))
    assert result.returncode == 2 and b"light samples are more than phongray renders" in result.stderr


# -- the command line as a careful user expects it ---------------------------------------------------------

import io  # noqa: E402
from importlib.metadata import metadata, version  # noqa: E402

from service import cli  # noqa: E402

from server import running_server  # noqa: E402

SUBCOMMANDS = ["render", "validate", "grade", "grade-class", "serve", "schema"]


def test_version_from_the_package_metadata():
    expected = f"phongray {version('phongray')}\n".encode()
    for args in (["--version"], ["-V"]):
        assert run(*args).stdout == expected
    done = subprocess.run([sys.executable, "-m", "phongray", "-V"], capture_output=True, timeout=60)
    assert done.stdout == expected


def test_every_option_has_help_and_shows_its_default():
    serve = run("serve", "--help").stdout.decode()
    assert "port to listen on (default: 8000)" in serve and "(default: 127.0.0.1)" in serve
    render = run("render", "--help").stdout.decode()
    for option in ("--width", "--height", "--samples", "--threads", "--quiet", "--server", "--api-key", "--cluster"):
        assert option in render
    parser = cli.build_parser()
    for name in SUBCOMMANDS:
        sub = parser._subparsers._group_actions[0].choices[name]  # type: ignore[union-attr]
        for action in sub._actions:
            assert action.help, (name, action.dest)


def test_validate_prints_the_json_line_of_every_problem(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text(
        '{"camera": {"position": [0, 0, 5],\n "look_At": [0, 0, 0]},\n "image": {"width": 4, "height": 3},\n'
        ' "materials": {"gold": {}},\n "objects": [{"type": "sphere", "material": "glod",\n'
        '   "center": [0, 0, 0], "radius": -1}]}\n'
    )
    assert main(["validate", str(bad)]) == 1
    assert capsys.readouterr().out.splitlines() == [  # in the order of their lines
        f"{bad}:1: camera.look_at: required",
        f"{bad}:2: camera.look_At: unknown key (did you mean 'look_at'?)",
        f"{bad}:5: objects[0].material: unknown material 'glod' (did you mean 'gold'?)",
        f"{bad}:6: objects[0].radius: must be > 0",
    ]
    syntax = tmp_path / "syntax.json"
    syntax.write_text('{"camera": {\n  "x": 1,,\n}}')
    assert main(["validate", str(syntax)]) == 1
    assert capsys.readouterr().out.startswith(f"{syntax}:2: invalid JSON:")


@pytest.mark.parametrize(
    "option, value, says",
    [
        ("--tolerance", "-1", "tolerance: must be between 0 and 255"),
        ("--max-fraction", "5", "max_fraction: must be between 0 and 1"),
    ],
)
def test_grading_thresholds_are_checked_as_over_http(tmp_path, capsys, option, value, says):
    scene = SCENES / "01_three_spheres.json"
    image = tmp_path / "same.png"
    image.write_bytes((SCENES / "01_three_spheres.png").read_bytes())
    assert main(["grade", str(scene), str(image), option, value]) == 2
    assert capsys.readouterr().err == f"phongray: {says}\n"


def test_an_output_that_is_not_a_png_is_refused(tmp_path, capsys):
    out = tmp_path / "x.jpg"
    assert main(["render", str(SCENES / "01_three_spheres.json"), "-o", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"phongray: {out}: phongray writes PNG images; name the output *.png (or - for standard output)\n"
    )
    assert not out.exists()


def test_server_urls_without_a_scheme_and_api_keys(tmp_path, capsys, monkeypatch):
    scene = str(SCENES / "01_three_spheres.json")
    with running_server(tmp_path, api_key="sesame") as (url, _):
        bare = url.removeprefix("http://")
        assert main(["validate", scene, "--server", bare, "--api-key", "sesame"]) == 0
        assert main(["validate", scene, "--server", bare, "--api-key", "wrong"]) == 2
        assert "401" in capsys.readouterr().err
        monkeypatch.setenv("PHONGRAY_API_KEY", "sesame")
        out = tmp_path / "a.png"
        assert main(["render", scene, "-o", str(out), "--server", bare]) == 0
        assert decode_png(out.read_bytes()).shape == (120, 160, 3)


@pytest.mark.parametrize(
    "url, says",
    [
        ("http://[::1", "--server: 'http://[::1' is not a URL (Invalid IPv6 URL)"),
        ("127.0.0.1:99999", "--server: '127.0.0.1:99999' is not a URL (Port out of range 0-65535)"),
        ("ftp://host", "--server: 'ftp://host' is not the http:// or https:// URL of a server"),
    ],
)
def test_a_server_url_that_names_no_server_is_one_line_and_exit_2(tmp_path, capsys, url, says):
    scene = str(SCENES / "01_three_spheres.json")
    class_folder = Path(__file__).resolve().parent.parent / "examples" / "class"
    for args in (
        ["render", scene, "-o", str(tmp_path / "a.png")],
        ["grade-class", str(class_folder / "scenes"), str(class_folder / "submissions"), "-o", str(tmp_path / "r")],
    ):
        assert main([*args, "--server", url]) == 2
        assert capsys.readouterr().err == f"phongray: {says}\n"


@pytest.mark.parametrize(
    "option, value, says",
    [
        ("--run-timeout", "inf", "'inf': must be at most 604800"),
        ("--run-timeout", "1e12", "'1e12': must be at most 604800"),
        ("--memory", "99999999999999999999999G", "at most 1024T (a pebibyte)"),
        ("--processes", "99999999999", "must be at most 4194304"),
    ],
)
def test_a_limit_beyond_what_a_run_can_be_given_is_refused_as_an_option(tmp_path, capsys, option, value, says):
    class_folder = Path(__file__).resolve().parent.parent / "examples" / "class"
    args = ["grade-class", str(class_folder / "scenes"), str(class_folder / "submissions"), "-o", str(tmp_path)]
    with pytest.raises(SystemExit) as exit_:
        main([*args, "--run", "python3 render.py {scene} {output}", option, value])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and f"argument {option}: " in err and says in err, err
    assert err.count("\n") == 1 and err.startswith("phongray grade-class: argument"), err  # (no usage first)


def test_a_tas_file_that_never_ends_or_waits_for_a_writer_is_refused_not_read(tmp_path, capsys):
    """A FIFO or a device given as a scene or a tasks file would wait forever or fill the memory: refused."""
    fifo = tmp_path / "scene.json"
    os.mkfifo(fifo)
    class_folder = Path(__file__).resolve().parent.parent / "examples" / "class"
    runs = [
        (["validate", str(fifo)], f"{fifo}: cannot read: a FIFO, not a regular file"),
        (
            ["render", "/dev/zero", "-o", str(tmp_path / "a.png")],
            "/dev/zero: cannot read: a device, not a regular file",
        ),
        (
            ["grade-class", str(class_folder / "scenes"), str(class_folder / "submissions"), "-o", str(tmp_path / "r")]
            + ["--tasks", str(fifo)],
            f"{fifo}: cannot read: a FIFO, not a regular file",
        ),
    ]
    for args, says in runs:
        assert main(args) == 2
        assert capsys.readouterr().err == f"phongray: {says}\n"


def test_validate_refuses_what_render_refuses(tmp_path, capsys):
    """A valid scene beyond what phongray renders (2^28 pixels) is no task scene: validate says so as render does."""
    data = json.loads((SCENES / "01_three_spheres.json").read_text())
    data["image"].update(width=100000, height=100000)
    path = tmp_path / "huge.json"
    path.write_text(json.dumps(data))
    says = "image: 100000×100000 pixels is more than phongray renders (268435456 pixels, 16384×16384)"
    assert main(["validate", str(path)]) == 1
    assert capsys.readouterr().out == f"{path}: {says}\n"
    assert main(["render", str(path), "-o", str(tmp_path / "a.png")]) == 2
    assert capsys.readouterr().err == f"phongray: {path}: {says}\n"


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_the_progress_bar_shows_elapsed_time_and_eta_and_an_interruption_gets_its_own_line(monkeypatch):
    err = _Terminal()
    monkeypatch.setattr(sys, "stderr", err)
    bar = cli.ProgressBar(delay=0.0)

    def interrupted(args):
        bar(0, 100)
        bar(40, 100)
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "build_parser", lambda: _parser_with(interrupted))
    assert main(["schema"]) == 130
    text = err.getvalue()
    assert "40.0%" in text and "elapsed, ETA" in text
    assert text.endswith("  \nphongray: interrupted\n")


def _parser_with(func):
    parser = cli.argparse.ArgumentParser(prog="phongray")
    parser.add_argument("command")
    parser.set_defaults(func=func)
    return parser


def test_licence_and_metadata():
    assert (SCENES.parent.parent / "LICENSE").read_text().startswith("MIT License")
    meta = metadata("phongray")
    assert meta["License-Expression"] == "MIT" and meta["Author"] == "The phongray developers"


def test_every_subcommand_runs_from_an_installed_wheel(tmp_path):
    """A wheel, not the source tree: a module the package forgets to ship shows up here."""
    root = SCENES.parent.parent
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(tmp_path / "dist"), str(root)],
        check=True,
        capture_output=True,
        timeout=300,
    )
    (wheel,) = (tmp_path / "dist").glob("phongray-*.whl")
    target = tmp_path / "site"
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", str(target), str(wheel)],
        check=True,
        capture_output=True,
        timeout=300,
    )
    env = {**os.environ, "PYTHONPATH": str(target)}
    where = subprocess.run(
        [sys.executable, "-c", "import service, bench, schemas, tracer; print(service.__file__)"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert where.stdout.startswith(str(target)), where.stderr
    for name in [*SUBCOMMANDS, "bench"]:
        done = subprocess.run(
            [sys.executable, "-m", "phongray", name, "--help"],
            cwd=tmp_path,
            env=env,
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert done.returncode == 0 and "usage:" in done.stdout, (name, done.stderr[-500:])


# -- the same answers with and without --server; no traceback anywhere ---------------------------------------

import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402


@pytest.fixture(scope="module")
def service_url(tmp_path_factory):
    with running_server(tmp_path_factory.mktemp("srv")) as (url, _):
        yield url


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Scenes and images every way they can be wrong, on lines of their own (so that lines are checked)."""
    root = tmp_path_factory.mktemp("files")
    data = json.loads((SCENES / "01_three_spheres.json").read_text())
    (root / "good.json").write_text(json.dumps(data, indent=2))
    bad = json.loads(json.dumps(data))
    bad["objects"][1]["radius"] = -1
    bad["objects"][2]["material"] = "glod"
    (root / "bad.json").write_text(json.dumps(bad, indent=2))
    (root / "syntax.json").write_text('{"camera": {\n  "x": 1,,\n}}')
    right = tracer_render(data)
    (root / "right.png").write_bytes(right)
    pixels = decode_png(right)
    (root / "dark.png").write_bytes(encode(pixels // 2))
    (root / "unshadowed.png").write_bytes(variant_render(data, "no-shadows"))
    (root / "small.png").write_bytes(encode(pixels[:10, :10]))
    (root / "text.png").write_text("not an image")
    buf = io.BytesIO()
    Image.fromarray(pixels).save(buf, format="JPEG")
    (root / "photo.jpg").write_bytes(buf.getvalue())
    return root


def tracer_render(data):
    import schemas
    import tracer

    return tracer.encode_png(tracer.render(schemas.validate_scene(data)))


def variant_render(data, name):
    import schemas
    import tracer
    from tracer.scene.variants import VARIANTS

    return tracer.encode_png(tracer.Renderer(schemas.validate_scene(data), VARIANTS[name][0]).pixels())


def encode(pixels):
    import tracer

    return tracer.encode_png(np.ascontiguousarray(pixels))


BOTH_WAYS = [
    ("render", "bad.json", "-o", "{tmp}/x.png", "-q"),
    ("render", "syntax.json", "-o", "{tmp}/x.png", "-q"),
    ("render", "missing.json", "-o", "{tmp}/x.png", "-q"),
    ("render", "good.json", "-o", "{tmp}/x.png", "-q"),
    ("validate", "bad.json"),
    ("validate", "syntax.json"),
    ("validate", "good.json"),
    ("grade", "bad.json", "right.png"),
    ("grade", "good.json", "right.png"),
    ("grade", "good.json", "right.png", "--json"),
    ("grade", "good.json", "dark.png"),
    ("grade", "good.json", "dark.png", "--json"),
    ("grade", "good.json", "unshadowed.png"),
    ("grade", "good.json", "unshadowed.png", "--json"),
    ("grade", "good.json", "unshadowed.png", "--no-diagnosis"),
    ("grade", "good.json", "small.png"),
    ("grade", "good.json", "text.png"),
    ("grade", "good.json", "photo.jpg"),
    ("grade", "good.json", "missing.png"),
    ("grade", "good.json", "right.png", "--tolerance", "300"),
]


@pytest.mark.parametrize("args", BOTH_WAYS, ids=lambda a: "-".join(a).replace("{tmp}/", ""))
def test_the_same_exit_code_and_words_with_and_without_server(args, files, service_url, tmp_path, capsys):
    argv = [
        str(files / a) if a.endswith((".json", ".png", ".jpg")) and "{tmp}" not in a else a.format(tmp=tmp_path)
        for a in args
    ]
    local = (main(argv), *capsys.readouterr())
    remote = (main([*argv, "--server", service_url]), *capsys.readouterr())
    assert remote == local
    assert "Traceback" not in local[2] and local[2].count("\n") <= 1


def test_an_invalid_scene_is_bad_input_for_grade_exit_2_not_a_fail(files, service_url, capsys):
    for extra in ([], ["--server", service_url]):
        assert main(["grade", str(files / "bad.json"), str(files / "right.png"), *extra]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"phongray: {files}/bad.json:") and ": objects[1].radius: must be > 0" in err


def test_grades_print_in_words_and_as_json(files, capsys):
    assert main(["grade", str(files / "good.json"), str(files / "right.png")]) == 0
    out = capsys.readouterr().out
    assert out.startswith("PASS\n  off even nearby: 0.00 % of the pixels (at most 0.10 % may be)\n")
    assert "PSNR identical images" in out and "None" not in out
    assert main(["grade", str(files / "good.json"), str(files / "dark.png")]) == 1
    first = capsys.readouterr().out.splitlines()[0]
    assert first.startswith("FAIL: ") and first.endswith(
        "% of the pixels are off even nearby (nothing around them within 2 levels, one way or the other); at most "
        "0.10 % may be"
    )
    assert main(["grade", str(files / "good.json"), str(files / "dark.png"), "--json"]) == 1
    result = json.loads(capsys.readouterr().out)
    assert result["passed"] is False and result["reason"].endswith("at most 0.10 % may be")
    assert result["fraction_off_nearby"] > 0.5 and result["psnr"] > 0


def test_a_failing_grade_names_the_likely_mistake_and_a_pass_gets_none(files, service_url, capsys):
    for extra in ([], ["--server", service_url]):
        assert main(["grade", str(files / "good.json"), str(files / "unshadowed.png"), *extra]) == 1
        lines = capsys.readouterr().out.splitlines()
        assert lines[6].startswith(
            "Likely: no shadow rays — the submission matches the reference rendered with "
            "that mistake (0.00 % of pixels off)"
        )
        assert main(["grade", str(files / "good.json"), str(files / "unshadowed.png"), "--json", *extra]) == 1
        found = json.loads(capsys.readouterr().out)["diagnosis"]
        assert found["causes"][0]["variant"] == "no-shadows" and found["causes"][0]["passes"] is True
        assert main(["grade", str(files / "good.json"), str(files / "right.png"), "--json", *extra]) == 0
        assert json.loads(capsys.readouterr().out)["diagnosis"] is None
        assert main(["grade", str(files / "good.json"), str(files / "unshadowed.png"), "--no-diagnosis", *extra]) == 1
        assert "Likely" not in capsys.readouterr().out


def test_an_image_is_read_no_further_than_the_limit(files, service_url, capsys, monkeypatch):
    monkeypatch.setenv("PHONGRAY_MAX_IMAGE_BYTES", "1000")
    for extra in ([], ["--server", service_url]):
        assert main(["grade", str(files / "good.json"), "/dev/zero", *extra]) == 2  # a file without end
        assert capsys.readouterr().err == (
            "phongray: /dev/zero: larger than the limit max_image_bytes = 1000 bytes (PHONGRAY_MAX_IMAGE_BYTES)\n"
        )


def test_compare_takes_grades_options(files, capsys):
    """--no-diagnosis, as grade takes it (compare has no scene, so names no mistake either way)."""
    for extra in ([], ["--no-diagnosis"]):
        assert main(["compare", str(files / "right.png"), str(files / "dark.png"), "--json", *extra]) == 1
        result = json.loads(capsys.readouterr().out)
        assert result["passed"] is False and result["diagnosis"] is None


def test_compare_grades_two_images_without_a_scene(files, capsys, tmp_path):
    assert main(["compare", str(files / "right.png"), str(files / "right.png"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["max_error"] == 0
    heat = str(tmp_path / "h.png")
    assert main(["compare", str(files / "right.png"), str(files / "dark.png"), "--heatmap", heat]) == 1
    assert capsys.readouterr().out.startswith("FAIL: ") and (tmp_path / "h.png").exists()
    for image, says in (
        ("small.png", "small.png: image is 10×10 pixels, the reference is 160×120"),
        ("photo.jpg", "photo.jpg: image is a JPEG; PNG or PPM required"),
    ):
        assert main(["compare", str(files / "right.png"), str(files / image)]) == 2
        assert capsys.readouterr().err == f"phongray: {files}/{says}\n"
    assert main(["compare", str(files / "photo.jpg"), str(files / "right.png")]) == 2
    assert capsys.readouterr().err == f"phongray: {files}/photo.jpg: image is a JPEG; PNG or PPM required\n"


def test_no_traceback_for_a_closed_pipe(tmp_path):
    read, write = os.pipe()
    os.close(read)  # as `phongray schema | head` once head has exited
    for args in (["schema"], ["render", str(SCENES / "01_three_spheres.json"), "-o", "-", "-q"]):
        done = subprocess.run(
            [sys.executable, "-m", "service.cli", *args], stdout=write, stderr=subprocess.PIPE, timeout=60
        )
        assert b"Traceback" not in done.stderr and b"Error" not in done.stderr, done.stderr
        assert done.returncode == 1
    os.close(write)


@pytest.mark.parametrize(
    "args, says",
    [
        (["serve", "--port", "99999"], b"99999 is not a TCP port (0-65535)".replace(b"-", "–".encode())),
        (["validate", str(SCENES / "01_three_spheres.json"), "--server", "127.0.0.1:notaport"], b"is not a URL"),
        (["validate", str(SCENES / "01_three_spheres.json"), "--server", "http://127.0.0.1:99999"], b"is not a URL"),
        (
            ["render", str(SCENES / "01_three_spheres.json"), "-o", "x.png", "--cluster", "garbage"],
            b"not a Dask scheduler address",
        ),
    ],
)
def test_bad_arguments_give_one_line_and_exit_2(args, says, tmp_path):
    done = subprocess.run([sys.executable, "-m", "service.cli", *args], capture_output=True, timeout=60, cwd=tmp_path)
    assert done.returncode == 2 and b"Traceback" not in done.stderr and says in done.stderr, done.stderr
    assert done.stderr.count(b"\n") <= 2  # argparse adds its usage line


def test_serve_on_a_port_in_use_is_one_line(tmp_path):
    import socket

    with socket.create_server(("127.0.0.1", 0)) as taken:
        port = taken.getsockname()[1]
        done = subprocess.run(
            [sys.executable, "-m", "service.cli", "serve", "--port", str(port)], capture_output=True, timeout=60
        )
    assert done.returncode == 2 and done.stderr.startswith(f"phongray: cannot listen on 127.0.0.1:{port}: ".encode())
    assert b"Traceback" not in done.stderr


def test_a_wrong_setting_in_the_environment_is_one_line_told_before_the_port_is_taken():
    """The setting is checked first: on a port already in use (as 8000 is when another server runs), the wrong
    setting is what is told, not "address already in use"."""
    import socket

    with socket.create_server(("127.0.0.1", 0)) as taken:
        port = taken.getsockname()[1]
        done = subprocess.run(
            [sys.executable, "-m", "service.cli", "serve", "--port", str(port)],
            capture_output=True,
            timeout=60,
            env={**os.environ, "PHONGRAY_MAX_PIXELS": "lots"},
        )
    assert done.returncode == 2 and done.stderr.startswith(b"phongray: PHONGRAY_MAX_PIXELS: "), done.stderr
    assert done.stderr.count(b"\n") == 1


def test_python_m_phongray_works_in_a_folder_with_a_students_modules(tmp_path):
    for name in ("tracer.py", "service.py", "schemas.py"):
        (tmp_path / name).write_text("raise SystemExit('a student module was imported')\n")
    done = subprocess.run(
        [sys.executable, "-m", "phongray", "render", str(SCENES / "07_spotlights.json"), "-o", "out.png", "-q"],
        cwd=tmp_path,
        capture_output=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert decode_png((tmp_path / "out.png").read_bytes()).shape == (120, 160, 3)


def test_with_a_cluster_dask_logs_nothing_of_its_own(tmp_path, capsys):
    """A lost scheduler makes Dask's client log reconnection tracebacks to the terminal; phongray's one line
    says what happened, so with --cluster Dask's loggers are quiet."""
    import logging

    import distributed  # noqa: F401

    free = socket_free_port()
    assert (
        main(
            [
                "render",
                str(SCENES / "01_three_spheres.json"),
                "-o",
                str(tmp_path / "x.png"),
                "--cluster",
                f"tcp://127.0.0.1:{free}",
                "--cluster-wait",
                "1",
            ]
        )
        == 2
    )
    assert capsys.readouterr().err.startswith("phongray: ")
    assert not logging.getLogger("distributed.client").isEnabledFor(logging.ERROR)


@pytest.mark.parametrize("command", ["render", "grade-class"])
@pytest.mark.parametrize("wait, asked", [("5", 5.0), ("0", 1.0), ("60", 10.0)])
def test_cluster_wait_bounds_the_wait_for_an_unreachable_scheduler(command, wait, asked, tmp_path, capsys, monkeypatch):
    """--cluster-wait 5 gives the scheduler 5 s to answer (not Dask's own 10 s, and then 5 s more for a
    worker); 0 still lets it answer (in 1 s); a longer wait keeps Dask's 10 s for the answer."""
    import distributed

    given = []

    def unreachable(address, timeout, **kw):
        given.append(timeout)
        raise OSError(f"Timed out trying to connect to {address} after {timeout:g} s")

    monkeypatch.setattr(distributed, "Client", unreachable)
    address = f"tcp://127.0.0.1:{socket_free_port()}"
    args = (
        ["render", str(SCENES / "07_spotlights.json"), "-o", str(tmp_path / "x.png")]
        if command == "render"
        else ["grade-class", "examples/class/scenes", "examples/class/submissions", "-o", str(tmp_path / "r")]
    )
    monkeypatch.chdir(SCENES.parent.parent)
    assert main([*args, "--cluster", address, "--cluster-wait", wait]) == 2
    assert given == [asked]
    assert f"cannot reach the Dask scheduler at {address}" in capsys.readouterr().err


def socket_free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_a_fifo_given_as_the_image_is_refused_not_waited_on(files, service_url, capsys, tmp_path):
    fifo = tmp_path / "student.png"
    os.mkfifo(fifo)
    for extra in ([], ["--server", service_url]):
        assert main(["grade", str(files / "good.json"), str(fifo), *extra]) == 2
        assert capsys.readouterr().err == f"phongray: {fifo}: a FIFO, not a regular file\n"
