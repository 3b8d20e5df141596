"""Line numbers of JSON values by their user-facing path (``objects[2].radius``).

Used to show an error next to the line it concerns.  The scanner is iterative,
so deeply nested input cannot exhaust the stack; it assumes the text is JSON
that has already parsed.
"""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from typing import TypedDict

#: deeper values are not located (a scene is never nested more than a few levels)
MAX_DEPTH = 64
_TOKEN = re.compile(r'\s*(?:("(?:[^"\\]|\\.)*")|([{}\[\]:,])|(-?[0-9][0-9eE.+\-]*|true|false|null))', re.S)


def value_lines(text: str, limit: int = 200_000) -> dict[str, int]:  # noqa: C901 (one JSON scanner)
    """Map from path to the 1-based line where that value starts (for at most ``limit`` values)."""
    out: dict[str, int] = {}
    stack: list[list] = []  # frames: [kind, path, next index or pending key]
    pos, n = 0, len(text)
    line_starts = [0] + [m.end() for m in re.finditer("\n", text)]

    def line_of(offset: int) -> int:
        lo, hi = 0, len(line_starts) - 1
        while lo < hi:
            mid = (lo + hi + 1) // 2
            if line_starts[mid] <= offset:
                lo = mid
            else:
                hi = mid - 1
        return lo + 1

    def current_path() -> str | None:
        if not stack:
            return ""
        kind, path, slot = stack[-1]
        if kind == "[":
            return f"{path}[{slot}]"
        return f"{path}.{slot}" if path else str(slot)

    expecting_key = False
    while pos < n and len(out) < limit and len(stack) <= MAX_DEPTH:
        m = _TOKEN.match(text, pos)
        if not m:
            break
        start = m.start(1) if m.group(1) else m.start(2) if m.group(2) else m.start(3)
        pos = m.end()
        string, punct, scalar = m.groups()
        if punct in ("{", "["):
            path = current_path()
            if path is not None:
                out.setdefault(path, line_of(start))
            stack.append([punct, path or "", 0 if punct == "[" else None])
            expecting_key = punct == "{"
        elif punct in ("}", "]"):
            stack.pop() if stack else None
            expecting_key = False
        elif punct == ",":
            if stack and stack[-1][0] == "[":
                stack[-1][2] += 1
            expecting_key = bool(stack) and stack[-1][0] == "{"
        elif punct == ":":
            expecting_key = False
        elif string is not None and expecting_key:
            stack[-1][2] = json.loads(string)
            out.setdefault(current_path() or "", line_of(start))
        else:
            path = current_path()
            if path is not None:
                out.setdefault(path, line_of(start))
    return out


def line_for(lines: dict[str, int], path: str) -> int | None:
    """The line of ``path`` or of its nearest enclosing value that is known."""
    while path:
        if path in lines:
            return lines[path]
        cut = max(path.rfind("."), path.rfind("["))
        path = path[:cut] if cut > 0 else ""
    return None


_SYNTAX_LINE = re.compile(r"^invalid JSON: .* at line (\d+) column \d+$")
#: longer documents are not scanned for lines (a courtesy that must stay cheap)
MAX_SCANNED = 1_000_000


class Located(TypedDict):
    """A problem of a scene as the service answers it (and the command line prints it): where, what, and the
    line of the JSON text (None where unknown)."""

    path: str
    message: str
    line: int | None


def located(problems: list[tuple[str, str]], text: bytes | str) -> list[Located]:
    """Every problem with its path, message and the line of the JSON text it concerns (None where unknown):
    the line of the value for a path, the line the parser names for a syntax error."""
    lines: dict[str, int] = {}
    if len(text) <= MAX_SCANNED and any(path for path, _ in problems):
        try:
            lines = value_lines(text.decode("utf-8", "replace") if isinstance(text, bytes) else text)
        except Exception:  # positions are a courtesy; a scanner failure must not hide the errors
            lines = {}
    out: list[Located] = []
    for path, message in problems:
        syntax = None if path else _SYNTAX_LINE.match(message)
        line = line_for(lines, path) if path else int(syntax.group(1)) if syntax else None
        out.append({"path": path, "message": message, "line": line})
    return out


def as_lines(name: str, problems: list[tuple[str, str]], text: bytes | str) -> list[str]:
    """``NAME:LINE: path: message`` per problem (``NAME: path: message`` where the line is unknown)."""
    return format_located(name, located(problems, text))


def _line_order(error: Located) -> float:
    line = error.get("line")
    return float(line) if isinstance(line, int) else float("inf")


def format_located(name: str, errors: Sequence[Located]) -> list[str]:
    """``NAME:LINE: path: message`` per located problem (``{"path", "message", "line"}``, as :func:`located`
    and the service's answers give them), in the order of their lines (those of no line, such as a missing
    top-level key, last)."""
    out = []
    for e in sorted(errors, key=_line_order):
        what = f"{e.get('path')}: {e.get('message')}" if e.get("path") else str(e.get("message"))
        out.append(f"{name}:{e['line']}: {what}" if e.get("line") else f"{name}: {what}")
    return out
