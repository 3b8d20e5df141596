"""The README and the pages under docs/ hold together: every relative link reaches a file, every page is linked
from the README and links back to it, and the README's two commands are the ones CI runs."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
PAGES = [README, *sorted((ROOT / "docs").glob("*.md"))]
CI = ROOT / ".ci" / "run"

FENCE = re.compile(r"^```.*?^```", re.S | re.M)
INLINE_CODE = re.compile(r"`[^`\n]*`")
LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
EXTERNAL = ("http://", "https://", "mailto:")


def links(text: str) -> list[str]:
    """The targets of the Markdown links and images in ``text``, outside code blocks and inline code."""
    return LINK.findall(INLINE_CODE.sub("", FENCE.sub("", text)))


def broken_links(page: Path) -> list[str]:
    """The relative links of ``page`` whose file (the link without its #fragment, from the page's folder) is missing."""
    broken = []
    for target in links(page.read_text()):
        if target.startswith(EXTERNAL) or target.startswith("#"):
            continue
        path = target.split("#", 1)[0]
        if not (page.parent / path).exists():
            broken.append(target)
    return broken


def sh_blocks(text: str) -> list[str]:
    return re.findall(r"^```sh\n(.*?)^```", text, re.S | re.M)


def test_every_relative_link_reaches_a_file():
    assert len(PAGES) > 1
    broken = {page.relative_to(ROOT).as_posix(): broken_links(page) for page in PAGES}
    assert not any(broken.values()), {page: targets for page, targets in broken.items() if targets}


def test_a_link_to_a_missing_file_is_found(tmp_path):
    """The check itself can fail: a missing file (with or without a fragment) is reported, and only that."""
    (tmp_path / "there.md").write_text("# There\n")
    (tmp_path / "sub").mkdir()
    page = tmp_path / "sub" / "page.md"
    page.write_text(
        "[up](../there.md) [up, a heading](../there.md#there) [here](#top) [web](https://example.com/x.md)\n"
        "[mail](mailto:someone@example.com) ![a picture](missing.png) [gone](../gone.md#part)\n"
        "`[in code](nowhere.md)`\n\n```\n[in a block](nowhere.md)\n```\n")
    assert broken_links(page) == ["missing.png", "../gone.md#part"]


def test_every_page_is_linked_from_the_readme_and_links_back():
    linked = {(ROOT / target.split("#", 1)[0]).resolve() for target in links(README.read_text())}
    for page in PAGES[1:]:
        assert page.resolve() in linked, f"{page.name} is not linked from the README"
        text = page.read_text()
        assert text.startswith("# "), f"{page.name} does not start with a title"
        assert "../README.md" in links(text), f"{page.name} does not link back to the README"


def test_the_readmes_two_commands_are_the_ones_ci_runs():
    """The first two ```sh blocks of the README (render an example; run the tests), each one line, verbatim in
    .ci/run."""
    render, tests = (block.strip() for block in sh_blocks(README.read_text())[:2])
    assert "\n" not in render and "\n" not in tests
    assert "phongray render examples/" in render and render.startswith("python3 -m venv .venv && ")
    assert tests.startswith("python3 -m venv .venv && ") and tests.endswith("python -m pytest -q")
    ci = [line.strip() for line in CI.read_text().splitlines()]
    assert render in ci, "the README's render command is not in .ci/run"
    assert tests in ci, "the README's test command is not in .ci/run"


def test_the_render_commands_image_is_ignored_by_git():
    """CI runs the README's render command in the clone: what it writes is not left as a change to commit."""
    render = sh_blocks(README.read_text())[0]
    out = render.split(" -o ", 1)[1].split()[0]
    ignored = [line.strip() for line in (ROOT / ".gitignore").read_text().splitlines()]
    assert out in ignored or f"/{out}" in ignored, out
