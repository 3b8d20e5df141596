"""Turning every way a scene can be wrong into ``path: message`` lines."""

from __future__ import annotations

import difflib
import json
from typing import Any

from pydantic import ValidationError

from . import scene as models

#: the models of the tagged unions by tag (pydantic puts the tags into error locations)
_TAGGED = {
    "sphere": models.Sphere,
    "plane": models.Plane,
    "triangle": models.Triangle,
    "mesh": models.Mesh,
    "ambient": models.AmbientLight,
    "directional": models.DirectionalLight,
    "point": models.PointLight,
    "spot": models.SpotLight,
    "area": models.AreaLight,
}


class SceneError(ValueError):
    """A scene that breaks the format; ``problems`` lists ``(path, message)``."""

    def __init__(self, problems: list[tuple[str, str]]):
        self.problems = [(_clip(path), _clip(message)) for path, message in problems]
        super().__init__("\n".join(format_problem(p) for p in problems))

    def __reduce__(self) -> tuple[type[SceneError], tuple[list[tuple[str, str]]]]:
        """Pickled as its problems (its one argument), so that one raised in a pool's process reaches the
        grading process as itself, not as a broken pool."""
        return type(self), (self.problems,)


#: paths and messages echo the user's keys and names; longer ones are cut in the middle
MAX_TEXT = 240


def _clip(text: str) -> str:
    if len(text) <= MAX_TEXT:
        return text
    return f"{text[: MAX_TEXT // 2]}…({len(text) - MAX_TEXT} characters)…{text[-MAX_TEXT // 4 :]}"


def format_problem(problem: tuple[str, str]) -> str:
    path, message = problem
    return f"{path}: {message}" if path else message


def path_of(loc: tuple[Any, ...]) -> str:
    """``('objects', 2, 'sphere', 'radius')`` → ``objects[2].radius``."""
    out = ""
    previous: Any = None
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        elif isinstance(previous, int) and part in _TAGGED:
            pass  # the union branch chosen by "type" is not part of the user's path
        else:
            out += f".{part}" if out else str(part)
        previous = part
    return out


def suggestion(name: Any, known: Any) -> str:
    """`` (did you mean 'x'?)`` for the closest of ``known`` to a misspelt ``name``, or nothing."""
    if not isinstance(name, str):
        return ""
    close = difflib.get_close_matches(name, [k for k in known if isinstance(k, str)], n=1, cutoff=0.6)
    if not close and name.lower() in {str(k).lower() for k in known}:
        close = [next(k for k in known if str(k).lower() == name.lower())]
    return f" (did you mean '{close[0]}'?)" if close else ""


#: keys people write for a model's field of another name, which no spelling distance finds
_MEANT = {models.Material: {"color": "diffuse", "colour": "diffuse"}}
#: what a colour that is neither an array nor a number is told
COLOUR = "must be an array of 3 numbers [r, g, b] or one number (a grey: 0.5 means [0.5, 0.5, 0.5])"


def _key_suggestion(name: Any, model: Any) -> str:
    meant = _MEANT.get(model, {}).get(name)
    return f" (did you mean '{meant}'?)" if meant else suggestion(name, model.model_fields)


def _is_colour(loc: tuple[Any, ...]) -> bool:
    """Whether ``loc`` is a colour field (an RGB triple, or one number for a grey)."""
    model = _model_at(loc[:-1]) if loc else None
    field = model.model_fields.get(loc[-1]) if model is not None else None
    return field is not None and any(getattr(m, "func", None) is models._expand_grey for m in field.metadata)


def _model_at(loc: tuple[Any, ...]) -> Any:
    """The model whose fields the location ``loc`` lies among (union tags included), or None."""
    parts = list(loc)
    if not parts:
        return models.Scene
    head = parts[0]
    if head in ("camera", "image") and len(parts) == 1:
        return models.Camera if head == "camera" else models.Image
    if head == "materials" and len(parts) == 2:
        return models.Material
    if head == "materials" and len(parts) == 3 and parts[2] == "checker":
        return models.Checker
    if head in ("objects", "lights") and len(parts) == 3 and isinstance(parts[1], int):
        return _TAGGED.get(parts[2])
    return None


def _message(err: dict[str, Any]) -> str:  # noqa: C901 (one plain branch per kind of Pydantic error)
    kind, ctx = err["type"], err.get("ctx") or {}
    if kind == "missing":
        return "required"
    if kind == "extra_forbidden":
        model = _model_at(tuple(err["loc"][:-1]))
        return "unknown key" + (_key_suggestion(err["loc"][-1], model) if model is not None else "")
    if kind in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
        op = {"greater_than": ">", "greater_than_equal": "≥", "less_than": "<", "less_than_equal": "≤"}[kind]
        bound = next(iter(ctx.values()))
        return f"must be {op} {bound:g}" if isinstance(bound, (int, float)) else err["msg"]
    if kind == "union_tag_invalid":
        expected = [t.strip().strip("'") for t in str(ctx.get("expected_tags", "")).split(",")]
        return (
            f"unknown type {ctx.get('tag')!r}{suggestion(ctx.get('tag'), expected)} "
            f"(expected one of {ctx.get('expected_tags')})"
        )
    if kind == "union_tag_not_found":
        return "'type' is required"
    if kind in ("float_type", "float_parsing"):
        return "must be a number"
    if kind in ("int_type", "int_parsing", "int_from_float"):
        return "must be an integer"
    if kind == "finite_number":
        return "must be a finite number"
    if kind == "too_long":
        return f"{_has(ctx.get('actual_length'))}, expected {ctx.get('max_length')}"
    if kind == "too_short":
        return f"{_has(ctx.get('actual_length'))}, expected at least {ctx.get('min_length')}"
    if kind in ("tuple_type", "list_type"):
        return COLOUR if _is_colour(tuple(err["loc"])) else "must be an array"
    if kind in ("dict_type", "model_type", "model_attributes_type"):
        return "must be an object"
    if kind == "literal_error":
        return f"must be {ctx.get('expected')}"
    if kind == "string_type":
        return "must be a string"
    if kind == "string_too_short":
        return "must not be empty"
    if kind == "string_too_long":
        return f"must be at most {ctx.get('max_length')} characters long"
    if kind == "string_pattern_mismatch":
        return "must not contain control characters (line breaks, tabs, ...)"
    return err["msg"]


def _has(count: Any) -> str:
    return f"has {count} element" + ("" if count == 1 else "s")


def _expected_length(loc: tuple[Any, ...]) -> int:
    """How many elements the fixed-length array at ``loc`` has (3, but 2 for an area light's samples)."""
    return 2 if loc and loc[-1] == "samples" else 3


def _tuple_missing(err: dict[str, Any]) -> bool:
    loc = err["loc"]
    return err["type"] == "missing" and bool(loc) and isinstance(loc[-1], int)


def problems_from_validation(errors: ValidationError | list[Any]) -> list[tuple[str, str]]:
    """``(path, message)`` per pydantic error (a ValidationError, or its errors with absolute locations)."""
    items: list[Any] = errors.errors(include_url=False) if isinstance(errors, ValidationError) else errors
    out: list[tuple[str, str]] = []
    seen: set[tuple[str, str]] = set()
    for err in items:
        loc = err["loc"]
        if _tuple_missing(err):  # a short array: report the array, once
            given = err.get("input")
            count = _has(len(given)) if isinstance(given, (list, tuple)) else "has too few elements"
            problem = (path_of(loc[:-1]), f"{count}, expected {_expected_length(loc[:-1])}")
        elif err["type"].startswith("union_tag"):
            problem = (path_of((*loc, "type")), _message(err))
        else:
            problem = (path_of(loc), _message(err))
        if problem not in seen:
            seen.add(problem)
            out.append(problem)
    return out


def _reject_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise ValueError(f"duplicate key {key!r}")
        out[key] = value
    return out


def _float(text: str) -> float:
    return float(text)


def _int(text: str) -> int:
    return int(text)


#: documents longer than this parse their numbers through Python functions: slower by a third, but the
#: interpreter can then switch threads during the parse instead of after it (a server's event loop waits)
YIELDING_PARSE = 256 * 1024


#: the parser's words for a syntax error, in plain ones (by the start of the parser's message)
_PLAIN = {
    "Expecting ',' delimiter": "a comma is missing between two items",
    "Expecting ':' delimiter": "a ':' is missing after the key",
    "Expecting property name": 'a key must be a string in double quotes ("name")',
    "Expecting value": 'a value is expected here (a number, a "string", true, false, null, [...] or {...})',
    "Unterminated string": 'a string is not closed (its closing " is missing)',
    "Invalid control character": "a line break or tab inside a string (write it as \\n or \\t)",
    "Extra data": "more text after the end of the JSON document",
    "Invalid \\escape": "an unknown escape after a backslash in a string (in a path, write \\\\ or /)",
}


def syntax_error(exc: json.JSONDecodeError) -> str:
    """A JSON syntax error in plain words, ending ``at line L column C`` (the place it concerns), with what JSON
    does not allow that people often write: comments, a comma after the last item, single quotes."""
    doc, pos = exc.doc, exc.pos
    if not doc.strip():  # (bytes that decode to no text at all: UTF-16 or UTF-32 marks)
        return "invalid JSON: no JSON text in the document (is it UTF-8?)"
    before = doc[:pos].rstrip()
    if doc.startswith(("//", "/*", "#"), pos):
        what = "a comment (JSON has no comments: delete it)"
    elif before.endswith(",") and doc.startswith(("}", "]"), pos):
        pos = len(before) - 1
        what = f"a comma after the last item, before '{doc[exc.pos]}' (JSON allows none there: delete it)"
    elif doc.startswith("'", pos):
        what = 'a string in single quotes (JSON strings take double quotes: "name")'
    elif pos >= len(doc.rstrip()):
        what = "the document ends too early (a closing '}', ']' or '\"' is missing)"
    else:
        what = next((plain for start, plain in _PLAIN.items() if exc.msg.startswith(start)), exc.msg)
    line = doc.count("\n", 0, pos) + 1
    column = pos - doc.rfind("\n", 0, pos)
    return f"invalid JSON: {what} at line {line} column {column}"


#: the longest whole number Python reads from text (sys.get_int_max_str_digits's default)
_MOST_DIGITS = 4300


def parse_json(text: str | bytes, shared: bool = True) -> Any:
    """Strict JSON: no NaN/Infinity tokens, no duplicate keys; errors as SceneError.

    ``shared=False`` says that no other thread waits for the interpreter (a
    command-line run): then even a long document parses at full speed."""
    yielding = shared and len(text) > YIELDING_PARSE
    numbers: dict[str, Any] = {"parse_float": _float, "parse_int": _int} if yielding else {}
    if not text or text.isspace():
        raise SceneError([("", "invalid JSON: the document is empty")])
    if isinstance(text, bytes) and (text.startswith((b"\xff\xfe", b"\xfe\xff")) or b"\0" in text[:4]):
        raise SceneError([("", "invalid JSON: the document is UTF-16 or UTF-32 text; send it as UTF-8")])
    try:
        return json.loads(text, parse_constant=_reject_constant, object_pairs_hook=_no_duplicates, **numbers)
    except json.JSONDecodeError as exc:
        raise SceneError([("", syntax_error(exc))]) from None
    except UnicodeDecodeError:
        raise SceneError([("", "invalid JSON: the document is not UTF-8 text")]) from None
    except RecursionError:
        raise SceneError([("", "invalid JSON: nested too deeply")]) from None
    except ValueError as exc:
        if "integer string conversion" in str(exc):  # (Python's guard against quadratic int parsing)
            raise SceneError([("", f"invalid JSON: a whole number of more than {_MOST_DIGITS} digits")]) from None
        raise SceneError([("", f"invalid JSON: {exc}")]) from None
