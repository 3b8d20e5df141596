"""The README and the pages under docs/ hold together: every relative link reaches a file, every page is linked
from the README (a maintainer's page from docs/internals/, which the README links) and links back to it, the
README's two commands are the ones CI runs and what it says of the tests is true, and the pages a user reads
keep to what a user needs: no issue numbers, no commit hashes."""

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
#: the pages a user reads (the README and docs/*.md) and the maintainers' (docs/internals/)
USER_PAGES = [README, *sorted((ROOT / "docs").glob("*.md"))]
INTERNALS = ROOT / "docs" / "internals"
INTERNAL_PAGES = sorted(INTERNALS.glob("*.md"))
PAGES = USER_PAGES + INTERNAL_PAGES
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
        "`[in code](nowhere.md)`\n\n```\n[in a block](nowhere.md)\n```\n"
    )
    assert broken_links(page) == ["missing.png", "../gone.md#part"]


def linked_from(page: Path) -> set[Path]:
    return {(page.parent / target.split("#", 1)[0]).resolve() for target in links(page.read_text())}


def test_every_page_is_linked_from_the_readme_and_links_back():
    linked = linked_from(README)
    for page in USER_PAGES[1:]:
        assert page.resolve() in linked, f"{page.name} is not linked from the README"
        text = page.read_text()
        assert text.startswith("# "), f"{page.name} does not start with a title"
        assert "../README.md" in links(text), f"{page.name} does not link back to the README"


def test_the_maintainers_pages_are_linked_from_one_place():
    """The README links docs/internals/README.md, once; it links every other page of docs/internals/, and each
    links back to the README."""
    index = INTERNALS / "README.md"
    assert [t for t in links(README.read_text()) if "internals/" in t] == ["docs/internals/README.md"]
    assert INTERNAL_PAGES and index in INTERNAL_PAGES
    for page in INTERNAL_PAGES:
        assert page.read_text().startswith("# "), f"{page.name} does not start with a title"
        assert "../../README.md" in links(page.read_text()), f"{page.name} does not link back to the README"
        assert page == index or page.resolve() in linked_from(index), f"{page.name} is not linked from {index}"


#: what a maintainer's diary says and a user's page need not: "issue 37", "#45", a commit's hash (7 to 40 hex
#: digits, with a letter and a digit)
DIARY = re.compile(r"\bissues? \d+|(?<![\w&])#\d+\b|\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*\d)[0-9a-f]{7,40}\b")


def diary_words(text: str) -> list[str]:
    return [m.group(0) for m in DIARY.finditer(text)]


def test_the_pages_a_user_reads_hold_no_issue_numbers_or_commit_hashes():
    found = {page.relative_to(ROOT).as_posix(): diary_words(page.read_text()) for page in USER_PAGES}
    assert not any(found.values()), {page: words for page, words in found.items() if words}


def test_the_diary_check_can_fail():
    text = "as of issue 37, against 02a0769 (see #12); colour #fff, 1e100 and 4096×4096 are fine, so is 1234567"
    assert diary_words(text) == ["issue 37", "02a0769", "#12"]


def test_the_readme_says_how_many_browser_tests_are_skipped_without_chromium():
    """The tests of tests/test_e2e.py that take its ``browser`` fixture are the ones skipped without Chromium."""
    tree = ast.parse((ROOT / "tests" / "test_e2e.py").read_text())
    browser = [
        f.name
        for f in tree.body
        if isinstance(f, ast.FunctionDef) and f.name.startswith("test_") and "browser" in [a.arg for a in f.args.args]
    ]
    text = " ".join(README.read_text().split())
    assert browser and re.findall(r"(\d+) browser tests", text) == [str(len(browser))], browser
    assert f"without it those {len(browser)} are skipped" in text


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


def test_the_course_page_counts_the_mistakes_phongray_names():
    """The course page says how many classic mistakes a failing image is scored against, and how many more are
    named where the term fit points to them: today's numbers, whatever a change adds."""
    from tracer.scene.variants import MORE_VARIANTS, VARIANTS

    text = " ".join((ROOT / "docs" / "course.md").read_text().split())
    assert f"{len(VARIANTS)} classic mistakes in all, and {len(MORE_VARIANTS)} more" in text
