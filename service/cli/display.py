"""What the command line shows: a grade in words (or JSON), and a progress bar."""

from __future__ import annotations

import re
import sys
import time
from typing import Any

from ..diagnosis.records import together_readings
from ..images.figures import percent
from ..images.grading import GROSS_ALLOWED

#: what a terminal acts on rather than shows: C0 and C1 controls and DEL (escape sequences, carriage returns,
#: new lines), the bidirectional overrides and isolates that reorder a line, and lone surrogates (the stray
#: bytes of a name that is not UTF-8)
_UNSAFE = re.compile("[\x00-\x1f\x7f-\x9f\u061c\u200e\u200f\u202a-\u202e\u2066-\u2069\ud800-\udfff]")


def _escape(match: re.Match[str]) -> str:
    c = ord(match.group())
    if 0xDC80 <= c <= 0xDCFF:  # a byte that was not UTF-8, as Python keeps it (surrogateescape)
        return f"\\x{c - 0xDC00:02x}"
    return f"\\x{c:02x}" if c < 0x100 else f"\\u{c:04x}"


def printable(text: str) -> str:
    """A name for the terminal, on one line, its control characters escaped (``\\x1b[2J`` is shown, not run)."""
    return _UNSAFE.sub(_escape, text)


def describe(result: dict[str, Any]) -> list[str]:
    """A grade as lines for a person: the verdict (with its reason when it failed), then the numbers in units."""
    lines = [_pass(result) if result["passed"] else f"FAIL: {result['reason']}"]
    psnr = "identical images" if result["psnr"] is None else f"{result['psnr']:.2f} dB"
    lines += [
        f"  off even nearby: {percent(result['fraction_off_nearby'])} of the pixels "
        f"(at most {percent(result['max_fraction'])} may be)",
        f"  off: {percent(result['fraction_off'])} of the pixels (by more than {result['tolerance']:g} levels)",
        *_gross(result),
        f"  mean absolute error: {result['mean_abs_error']:.3f} levels; RMSE {result['rmse']:.3f}; PSNR {psnr}",
        f"  largest error: {result['max_error']} levels",
        f"  size: {result['width']}×{result['height']}; reference sha256 {result['reference_sha256']}",
    ]
    return lines + explained(result.get("diagnosis"))


def _gross(result: dict[str, Any]) -> list[str]:
    """A line for the pixels grossly off and the pixels not counted, where there are any."""
    gross, left = result.get("grossly_off") or 0, result.get("open_pixels") or 0
    lines = (
        [f"  grossly off: {gross} pixel{'s' if gross != 1 else ''} (at most {GROSS_ALLOWED} may be)"] if gross else []
    )
    return lines + ([f"  not counted: {left} pixels the scene format leaves open"] if left else [])


def _pass(result: dict[str, Any]) -> str:
    """PASS, and the accepted variant it passed as ("PASS, as rendered with a ray offset of 0.003 along the normal")."""
    accepted = result.get("accepted")
    return f"PASS, as rendered with {accepted}" if accepted else "PASS"


def explained(diagnosis: dict[str, Any] | None) -> list[str]:
    """A diagnosis (:meth:`service.diagnosis.Diagnosis.as_dict`) as lines: its sentence, then the evidence, in a
    student's words where the diagnosis has them (objects and lights by name or place)."""
    if not diagnosis:
        return []
    lines = [diagnosis["sentence"]]
    causes = diagnosis["causes"]
    if causes and causes[0].get("together"):  # (the evidence of the reading named first: the others' is the same)
        lines += [f"  {c['mistake']}: {c['evidence']}" for c in together_readings(causes)[0] if c.get("evidence")]
        causes = []
    elif causes and causes[0].get("share") is not None and not causes[0]["passes"]:  # the nearest explanations
        if diagnosis["sentence"].startswith("No known mistake fits exactly"):  # (none named: no lesser ones either)
            lines += [f"  also: {c['mistake']} (about {round(100 * c['share'])} %)" for c in causes[1:4]]
        causes = []
    if causes[1:4]:
        lines.append(
            "  also close: "
            + "; ".join(f"{c['mistake']} ({percent(c['fraction_off_nearby'])} off)" for c in causes[1:4])
        )
    for t in diagnosis["terms"][:3]:
        lines.append(f"  term: {_term(t)}")
    if diagnosis["objects"]:
        lines.append(
            "  failing pixels show: "
            + ", ".join(f"{_shown(s)} {percent(s['share'])}" for s in diagnosis["objects"][:4])
        )
    if diagnosis["lights"]:
        lines.append(
            "  lit there by: " + ", ".join(f"{_lit(s)} {percent(s['share'])}" for s in diagnosis["lights"][:4])
        )
    return lines


def _shown(share: dict[str, Any]) -> str:
    if share.get("words"):
        return str(share["words"])
    return "the background" if share["index"] < 0 else f"objects[{share['index']}] ({share['kind']})"


def _term(term: dict[str, Any]) -> str:
    if term.get("words"):
        return str(term["words"])
    what = term["name"] if term["light"] is None else f"{term['name']} of light {term['light']}"
    return f"{what} ×{term['scale']:.2f} of the reference's"


def _lit(share: dict[str, Any]) -> str:
    return str(share["words"]) if share.get("words") else f"lights[{share['index']}] ({share['kind']})"


def _clock(seconds: float) -> str:
    seconds = int(seconds)
    return (
        f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"
        if seconds >= 3600
        else f"{seconds // 60}:{seconds % 60:02d}"
    )


class ProgressBar:
    """A one-line progress bar on stderr, shown only on a terminal and only after a second."""

    def __init__(self, delay: float = 1.0, unit: str | None = None):
        self.start = time.monotonic()
        self.delay = delay
        self.unit = unit  # when set, the line shows "done/total unit" and an ETA
        self.shown = False
        self.enabled = sys.stderr.isatty()
        self.first: tuple[float, int] | None = None

    def __call__(self, done: int, total: int) -> None:
        now = time.monotonic()
        if self.first is None:
            self.first = (now, done)
        if not self.enabled or now - self.start < self.delay:
            return
        self.shown = True
        width = 30
        filled = int(width * done / max(total, 1))
        line = f"\r[{'#' * filled}{'.' * (width - filled)}] {100 * done / max(total, 1):5.1f}%"
        if self.unit:
            line += f" {done}/{total} {self.unit}"
        t0, d0 = self.first
        rate = (done - d0) / max(now - t0, 1e-9)
        eta = _clock((total - done) / rate) if rate > 0 else "?"
        line += f", {_clock(now - self.start)} elapsed, ETA {eta}  "
        ProgressBar.active = self
        sys.stderr.write(line)
        sys.stderr.flush()

    #: the bar on screen, so that an interruption can finish its line first
    active: ProgressBar | None = None

    def close(self) -> None:
        if self.shown and ProgressBar.active is self:
            sys.stderr.write("\n")
        ProgressBar.active = None
