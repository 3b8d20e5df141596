"""The commands of the README and of the pages under docs/ do what they say: binary uploads, Docker with mounted
folders, Dask on 127.0.0.1, and the class-grading command with its Gradescope output."""

import json
import re
from pathlib import Path

from fastapi.testclient import TestClient

from service.cli import main
from service.http.app import create_app
from service.settings import Settings

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
DOCS = {page.relative_to(ROOT).as_posix(): page.read_text() for page in PAGES}
COMMANDS = [
    line.strip()
    for text in DOCS.values()
    for block in re.findall(r"```sh\n(.*?)```", text, re.S)
    for line in block.splitlines()
]


def test_curl_uploads_scenes_as_they_are():
    uploads = [c for c in COMMANDS if c.startswith("curl") and "@examples/" in c and " -F " not in c]
    assert uploads and all("--data-binary @" in c for c in uploads), uploads
    assert not any("--data @" in c for c in COMMANDS)


def test_line_numbers_survive_an_upload_as_it_is_and_not_one_without_newlines():
    """What --data-binary sends (the file) keeps an error's line; what --data sends (no newlines) puts all on 1."""
    api = TestClient(create_app(Settings()))
    data = json.loads((Path(__file__).parent / "scenes" / "01_three_spheres.json").read_text())
    data["objects"][1]["radius"] = -1
    text = json.dumps(data, indent=2)
    line = next(i for i, t in enumerate(text.splitlines(), 1) if '"radius": -1' in t)
    for body, expected in ((text, line), (text.replace("\n", ""), 1)):
        res = api.post("/validate", content=body, headers={"content-type": "application/json"})
        assert [e["line"] for e in res.json()["errors"]] == [expected]
    assert line > 1


def test_docker_runs_with_mounted_folders_pass_the_users_id():
    mounted = [c for c in COMMANDS if c.startswith("docker run") and " -v " in c]
    assert mounted and all('--user "$(id -u):$(id -g)"' in c for c in mounted), mounted


def test_dask_dashboards_listen_on_127_0_0_1():
    dask = [c for c in COMMANDS if c.startswith(("dask scheduler", "dask worker"))]
    assert len(dask) == 2 and all("--dashboard-address 127.0.0.1:" in c for c in dask), dask


def test_the_class_section_shows_the_tas_layout_and_the_gradescope_output(tmp_path, monkeypatch):
    """docs/grading.md's command on the sample class (the README's too), and frank's results.json as the page
    shows it."""
    grading = DOCS["docs/grading.md"]
    section = grading[grading.index("\n## Grading a class\n") : grading.index("\n## Grading that explains\n")]
    assert "student-scenes/<student>/<task>.json" in section
    command = next(c for c in re.findall(r"```sh\n(.*?)```", section, re.S) if "grade-class" in c)
    assert command in DOCS["README.md"]
    argv = command.replace("\\\n", " ").split()[1:]
    assert argv[:2] == ["grade-class", "examples/class/scenes"] and "--student-scenes" in argv
    argv[argv.index("-o") + 1] = str(tmp_path / "report")
    monkeypatch.chdir(ROOT)
    assert main(argv) == 0
    start = section.index('{\n "score"')
    shown = json.loads(section[start : section.index("\n}\n", start) + 2])
    assert json.loads((tmp_path / "report" / "gradescope" / "frank" / "results.json").read_text()) == shown
