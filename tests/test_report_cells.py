"""The class report's table cells (service/classgrade/report.py): a long likely mistake or reason is shown whole,
wrapped within the cell, never cut."""

import re

from service.classgrade.report import COLUMNS, render_html

LONG = (
    "No known mistake fits exactly: most of the difference is the diffuse of the fifth light (area), which is "
    "missing (about 93 %); also what no ambient term changes"
)


def row(student: str, status: str, **more: object) -> dict:
    out = {c: None for c in COLUMNS}
    out.update(student=student, task="lights", status=status, reason="", mistakes=[], scene="shared")
    out.update(points=1.0, score=0.0, **more)
    return out


def test_a_long_likely_mistake_and_a_long_reason_are_shown_whole_and_wrap():
    reason = "subs/bo/lights.png: " + "image is truncated or corrupt: its data ends early or is damaged; " * 3
    rows = [row("ann", "fail", likely=LONG, fraction_off_nearby=0.5), row("bo", "invalid", reason=reason)]
    page = render_html(rows, [], ["ann", "bo"], ["lights"], "2 pairs")
    cells = re.findall(r'<td class="(?:fail|invalid)"><a [^>]*>[^<]*<small>(.*?)</small>', page)
    assert cells[0] == LONG  # the whole sentence, in the cell itself
    assert cells[1] == reason.split(": ", 1)[1]
    small = re.search(r"\.grid small \{([^}]*)\}", page)[1]
    assert "overflow-wrap: anywhere" in small and "overflow: hidden" not in small and "max-width" in small
